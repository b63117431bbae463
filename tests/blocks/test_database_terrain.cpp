// DatabaseTerrain: any window of a block database's terrain is the whole grid's samples there,
// with a cache of decoded blocks far smaller than the grid; the exact height range.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

#include "run_command.hpp"
#include "terralod/blocks/database_terrain.hpp"
#include "terralod/blocks/partition.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace tb = terralod::blocks;
namespace pm = terralod::pm;

namespace {

// A 129 x 113 terrain with a hole across a block border, built with 33-sample blocks.
struct Fixture {
  pm::Heightfield hf;
  std::string db;
};

const Fixture& fixture() {
  static const Fixture f = [] {
    pm::TerrainOptions to;
    to.width = 129, to.height = 113, to.seed = 5, to.relief = 700;
    Fixture x{pm::generate_terrain(to), ""};
    x.hf.transform = pm::GridTransform::north_up(500000.0, 4200000.0, 30.0, 20.0);
    std::vector<std::uint8_t> mask(x.hf.size(), 1);
    for (int r = 25; r < 40; ++r)
      for (int c = 28; c < 45; ++c) mask[std::size_t(r) * x.hf.width() + c] = 0;
    x.hf.set_mask(std::move(mask));
    x.db = (terralod::test::process_temp_dir("dbterrain") / "t.db").string();
    tb::DatabaseBuildOptions opt;
    opt.block_size = 33;
    opt.threads = 2;
    tb::build_database(x.hf, x.db, opt);
    return x;
  }();
  return f;
}

// Samples and mask of `w` against the whole grid's in `r`.
void expect_window(const pm::Heightfield& whole, const pm::Heightfield& w, const tb::SampleRect& r) {
  ASSERT_EQ(w.width(), r.width());
  ASSERT_EQ(w.height(), r.height());
  const pm::Heightfield expect = tb::block_heightfield(whole, r);
  EXPECT_EQ(w.transform, expect.transform);
  EXPECT_EQ(w.has_holes(), expect.has_holes());
  for (int j = 0; j < r.height(); ++j)
    for (int i = 0; i < r.width(); ++i) {
      ASSERT_EQ(w.valid(i, j), expect.valid(i, j)) << i << "," << j;
      if (w.valid(i, j)) {
        ASSERT_EQ(w.at(i, j), expect.at(i, j)) << i << "," << j;
      }
    }
}

}  // namespace

TEST(DatabaseTerrain, AnyWindowIsTheWholeGridsSamplesThere) {
  const Fixture& f = fixture();
  const auto db = tb::BlockDatabase::open(f.db);
  const pm::Heightfield whole = tb::read_database_terrain(db);
  ASSERT_EQ(whole.width(), f.hf.width());
  for (std::size_t i = 0; i < whole.size(); ++i) {
    ASSERT_EQ(whole.valid(i), f.hf.valid(i)) << i;
    if (whole.valid(i)) {
      ASSERT_EQ(whole[i], f.hf[i]) << i;
    }
  }
  // A cache of one block: every window decodes, evicts and decodes again.
  tb::DatabaseTerrain t(db, {.cache_bytes = 1, .threads = 2});
  EXPECT_EQ(t.width(), 129);
  EXPECT_EQ(t.height(), 113);
  std::mt19937 rng(3);
  std::vector<tb::SampleRect> rects = {
      {0, 0, 128, 112}, {32, 32, 32, 32}, {31, 0, 33, 112}, {128, 112, 128, 112}};
  for (int k = 0; k < 40; ++k) {
    std::uniform_int_distribution<int> cx(0, 128), cy(0, 112);
    int a = cx(rng), b = cx(rng), c = cy(rng), d = cy(rng);
    rects.push_back({std::min(a, b), std::min(c, d), std::max(a, b), std::max(c, d)});
  }
  for (const tb::SampleRect& r : rects) {
    SCOPED_TRACE(testing::Message() << r.col0 << "," << r.row0 << " .. " << r.col1 << "," << r.row1);
    const pm::Heightfield w = t.read(r);
    expect_window(whole, w, r);
    // Into a buffer of the caller's: the same samples, holes as NaN (the buffer's old values,
    // here a sentinel, are all overwritten).
    std::vector<double> buffer(r.samples(), -12345.0);
    t.read(r, buffer.data());
    for (std::size_t i = 0; i < buffer.size(); ++i) {
      if (w.valid(i)) {
        ASSERT_EQ(buffer[i], w[i]) << i;
      } else {
        ASSERT_TRUE(std::isnan(buffer[i])) << i;
      }
    }
  }
  // The cache's bound: the blocks of one batch (2 per thread, 4 here) at most.
  EXPECT_LE(t.peak_cache_bytes(), 4u * (33u * 33u * 9u + 256u));
  EXPECT_THROW(t.read({0, 0, 129, 10}), std::invalid_argument);
  EXPECT_THROW(t.read({-1, 0, 10, 10}), std::invalid_argument);
  std::vector<double> buffer(130 * 11);
  EXPECT_THROW(t.read({0, 0, 129, 10}, buffer.data()), std::invalid_argument);
}

TEST(DatabaseTerrain, HeightRangeIsTheValidSamplesExactRange) {
  const Fixture& f = fixture();
  const auto db = tb::BlockDatabase::open(f.db);
  tb::DatabaseTerrain t(db);
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (std::size_t i = 0; i < f.hf.size(); ++i)
    if (f.hf.valid(i)) lo = std::min(lo, f.hf[i]), hi = std::max(hi, f.hf[i]);
  double last = 0;
  const std::optional<tb::HeightRange> r = t.height_range([&](double p) {
    EXPECT_GE(p, last);
    last = p;
  });
  ASSERT_TRUE(r);
  EXPECT_EQ(r->lo, lo);
  EXPECT_EQ(r->hi, hi);
  EXPECT_EQ(last, 1.0);
}
