// Tests of the block stand-ins (BlockSummary's surface made by a node strategy): hand-derived
// errors, exact errors against the independent brute-force checker, the "block_summaries"
// blob version 2 round trip, version 1 decoding, corruption and hostile bytes, and
// build_database writing it.
#include <gtest/gtest.h>
#include <zlib.h>

#include <array>
#include <bit>
#include <cstdio>
#include <random>

#include "block_fixture.hpp"
#include "mesh_checker.hpp"
#include "terralod/blocks/active_region.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/progressive_mesh.hpp"

namespace tb = terralod::blocks;
namespace pm = terralod::pm;

namespace {

tb::StandinOptions standin(tb::StandinKind kind, std::size_t points,
                           pm::ErrorMetric metric = pm::ErrorMetric::Continuous) {
  tb::StandinOptions o;
  o.kind = kind;
  o.max_points = points;
  o.metric = metric;
  return o;
}

// The stand-in of s as a TriangleMesh of hf's sample indices (for the brute-force checker).
pm::TriangleMesh as_mesh(const tb::BlockSummary& s, int width) {
  pm::TriangleMesh m;
  for (const tb::StandinPoint& p : s.points) m.vertices.push_back(std::uint32_t(p.row * width + p.col));
  m.triangles = s.triangles;
  return m;
}

// Appends v's bytes as this (little-endian) host stores them: the documented little-endian
// layout written without the library's byte writer, which shifts byte by byte.
static_assert(std::endian::native == std::endian::little, "the hand-written blobs copy the host's bytes");
template <class T>
void append_le(std::vector<std::uint8_t>& o, T v) {
  for (std::uint8_t byte : std::bit_cast<std::array<std::uint8_t, sizeof(T)>>(v)) o.push_back(byte);
}
void reseal(std::vector<std::uint8_t>& b) {  // recompute the CRC trailer after an edit
  b.resize(b.size() - 4);
  append_le(b, std::uint32_t(::crc32(::crc32(0L, Z_NULL, 0), b.data(), uInt(b.size()))));
}

std::string decode_error(const tb::BlockGrid& g, const std::vector<std::uint8_t>& b) {
  try {
    tb::decode_block_summaries(g, b, "t.db");
  } catch (const tb::DatabaseError& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace

TEST(Standin, PeakByHand) {
  // 5 x 5 block, all heights 0 except the centre (2,2) = 8:
  //     0 0 0 0 0
  //     0 0 0 0 0
  //     0 0 8 0 0      two triangles (the corners, all 0): the centre is missed -> error 8.
  //     0 0 0 0 0      TIN of 5 points inserts the centre (largest error, on the diagonal): the
  //     0 0 0 0 0      fan of 4 triangles from it is 4 at (1,1), (2,1), ... where the samples
  //                    are 0 -> sample error 4. Between samples it is worse: at (2.5,1.5) the fan
  // triangle (0,0),(4,0),(2,2) is 8 * row / 2 = 6 while the full surface is 0 there (on cell
  // (2,1)'s diagonal (2,1)-(3,2), both ends 0) -> continuous error 6.
  // Grid of max 9 points -> P = 2: columns/rows 0, 2, 4, centre included; its cell [2,4]x[0,2]
  // is split along (2,0)-(4,2), so (2.5,1.5) lies in (2,0),(4,2),(2,2) with weight 1/2 on the
  // centre: 4 -> error 4 (continuous and at samples). Max 8 points -> P = 1: the two
  // triangles -> 8.
  pm::Heightfield hf(5, 5);
  hf.at(2, 2) = 8;
  const pm::ProgressiveMesh p = pm::ProgressiveMesh::build(hf);
  const tb::BlockSummary two = tb::summarize_block(p, {0, 0}, standin(tb::StandinKind::TwoTriangles, 4));
  EXPECT_EQ(two.standin, tb::StandinKind::TwoTriangles);
  EXPECT_EQ(two.points.size(), 4u);
  EXPECT_EQ(two.triangles.size(), 2u);
  EXPECT_DOUBLE_EQ(two.standin_error, 8.0);
  EXPECT_DOUBLE_EQ(two.tm_error, 8.0);
  const tb::BlockSummary tin = tb::summarize_block(p, {0, 0}, standin(tb::StandinKind::Tin, 5));
  EXPECT_EQ(tin.standin, tb::StandinKind::Tin);
  ASSERT_EQ(tin.points.size(), 5u);
  EXPECT_EQ(tin.triangles.size(), 4u);
  EXPECT_NE(std::find(tin.points.begin(), tin.points.end(), tb::StandinPoint{2, 2, 8.0}), tin.points.end());
  EXPECT_DOUBLE_EQ(tin.standin_error, 6.0);
  EXPECT_DOUBLE_EQ(tb::summarize_block(p, {0, 0}, standin(tb::StandinKind::Tin, 5, pm::ErrorMetric::Samples))
                       .standin_error,
                   4.0);
  EXPECT_DOUBLE_EQ(tb::standin_height(tin, 2.5, 1.5), 6.0);
  EXPECT_DOUBLE_EQ(tb::standin_height(tin, 2, 2), 8.0);
  EXPECT_DOUBLE_EQ(tb::standin_height(tin, 1, 1), 4.0);
  EXPECT_DOUBLE_EQ(tb::standin_height(tin, 3, 2), 4.0);
  const tb::BlockSummary grid9 = tb::summarize_block(p, {0, 0}, standin(tb::StandinKind::Grid, 9));
  EXPECT_EQ(grid9.points.size(), 9u);
  EXPECT_EQ(grid9.triangles.size(), 8u);
  EXPECT_DOUBLE_EQ(grid9.standin_error, 4.0);
  const tb::BlockSummary grid8 = tb::summarize_block(p, {0, 0}, standin(tb::StandinKind::Grid, 8));
  EXPECT_EQ(grid8.points.size(), 4u);
  EXPECT_DOUBLE_EQ(grid8.standin_error, 8.0);
  // Every stand-in keeps the corners: z00..z11 stay those of the block.
  for (const tb::BlockSummary* s : {&two, &tin, &grid9, &grid8}) {
    EXPECT_EQ(s->z00, 0);
    EXPECT_EQ(s->z11, 0);
    EXPECT_EQ(s->zmax, 8);
  }
  EXPECT_EQ(tb::parse_standin_kind("nonregular"), tb::StandinKind::NonRegularGrid);
  EXPECT_EQ(tb::parse_standin_kind("two-triangle"), tb::StandinKind::TwoTriangles);
  EXPECT_THROW(tb::parse_standin_kind("quad"), std::invalid_argument);
}

TEST(Standin, ErrorEqualsBruteForceForEveryKind) {
  // Generated blocks (whole-metre heights: the checker is exact), every kind at 3 sizes, both
  // metrics: the stored error is the independent checker's L-infinity error, the surface is an
  // exact single cover of the block, and its points are samples at their true heights.
  const terralod::test::BlockedTerrain t =
      terralod::test::make_blocked_terrain(65, 65, 33, /*seed=*/21, 30.0, 800.0);
  for (const auto& [k, blob] : t.blobs) {
    const pm::ProgressiveMesh p = pm::decode_pm(blob, "blob");
    const pm::Heightfield& hf = p.heightfield();
    for (tb::StandinKind kind : {tb::StandinKind::TwoTriangles, tb::StandinKind::Grid, tb::StandinKind::Tin,
                                 tb::StandinKind::NonRegularGrid})
      for (std::size_t n : {9u, 25u, 64u})
        for (pm::ErrorMetric metric : {pm::ErrorMetric::Continuous, pm::ErrorMetric::Samples}) {
          const tb::BlockSummary s = tb::summarize_block(p, k, standin(kind, n, metric));
          const std::string what = std::string(tb::standin_kind_name(kind)) + " " + std::to_string(n) +
                                   (metric == pm::ErrorMetric::Samples ? " samples" : " continuous") +
                                   " block (" + std::to_string(k.col) + "," + std::to_string(k.row) + ")";
          EXPECT_LE(s.points.size(), kind == tb::StandinKind::TwoTriangles ? 4u : n) << what;
          for (const tb::StandinPoint& q : s.points) ASSERT_EQ(q.z, hf.at(q.col, q.row)) << what;
          const terralod::test::MeshCheck c = terralod::test::check_mesh(hf, as_mesh(s, hf.width()));
          EXPECT_TRUE(c.topology_ok()) << what << ": " << c.describe();
          const double brute =
              metric == pm::ErrorMetric::Samples ? c.max_sample_error : c.max_continuous_error();
          EXPECT_NEAR(s.standin_error, brute, 1e-9) << what;
          // Per triangle: the brute-force error, rounded up to a float (relative 2^-23 at most).
          ASSERT_EQ(s.triangle_errors.size(), s.triangles.size()) << what;
          for (std::size_t i = 0; i < s.triangles.size(); ++i) {
            const auto& t = s.triangles[i];
            const auto sample = [&](std::uint32_t v) {
              return std::uint32_t(s.points[v].row * hf.width() + s.points[v].col);
            };
            const terralod::test::TriangleError te = terralod::test::triangle_error(
                hf, sample(t[0]), sample(t[1]), sample(t[2]), metric == pm::ErrorMetric::Continuous);
            EXPECT_GE(s.triangle_errors[i], te.max() - 1e-9) << what << " triangle " << i;
            EXPECT_LE(s.triangle_errors[i], te.max() * (1 + 1.2e-7) + 1e-9) << what << " triangle " << i;
            EXPECT_EQ(double(float(s.triangle_errors[i])), s.triangle_errors[i]);
          }
          if (kind == tb::StandinKind::TwoTriangles && metric == pm::ErrorMetric::Continuous) {
            EXPECT_EQ(s.standin_error, s.tm_error) << what;
          }
        }
  }
}

TEST(Standin, BlobVersion2RoundTripWithEveryKind) {
  // Mixed kinds, and one 300-point TIN (more than 256 points: 16-bit triangle indices).
  const std::vector<tb::StandinOptions> mix = {
      standin(tb::StandinKind::Tin, 32), standin(tb::StandinKind::Grid, 16),
      standin(tb::StandinKind::NonRegularGrid, 30), standin(tb::StandinKind::TwoTriangles, 4),
      standin(tb::StandinKind::Tin, 300)};
  const terralod::test::BlockedTerrain t =
      terralod::test::make_blocked_terrain(97, 81, 33, /*seed=*/4, 30.0, 600.0, mix);
  ASSERT_EQ(t.grid.block_count(), 9u);
  std::size_t big = 0, expect = 16 + 4;
  for (const tb::BlockSummary& s : t.summaries) {
    big += s.points.size() > 256;
    expect += 40 + 12 * s.points.size() + (s.points.size() > 256 ? 10 : 7) * s.triangles.size();
  }
  ASSERT_GT(big, 0u);
  const std::vector<std::uint8_t> blob = tb::encode_block_summaries(t.grid, t.summaries);
  EXPECT_EQ(blob.size(), expect);
  EXPECT_EQ(tb::decode_block_summaries(t.grid, blob, "t.db"), t.summaries);
  EXPECT_EQ(tb::encode_block_summaries(t.grid, tb::decode_block_summaries(t.grid, blob, "t.db")), blob);
}

// The blob joined from one record per block, streamed in pieces, is the blob encoded at once;
// each record decodes alone to its block's summary, and a record with a byte more or less fails.
TEST(Standin, RecordsJoinIntoTheBlob) {
  const std::vector<tb::StandinOptions> mix = {standin(tb::StandinKind::Tin, 32),
                                               standin(tb::StandinKind::Grid, 16),
                                               standin(tb::StandinKind::Tin, 300)};
  const terralod::test::BlockedTerrain t =
      terralod::test::make_blocked_terrain(97, 81, 33, /*seed=*/7, 30.0, 600.0, mix);
  std::vector<tb::BlockSummary> sums = t.summaries;
  sums[4] = tb::BlockSummary{};
  sums[4].empty = true;  // a block without samples: a 40-byte record
  std::vector<std::vector<std::uint8_t>> records;
  for (std::size_t i = 0; i < sums.size(); ++i) {
    records.push_back(tb::encode_block_summary_record(sums[i]));
    EXPECT_EQ(tb::decode_block_summary_record(t.grid, i, records.back(), "t.db"), sums[i]);
  }
  EXPECT_EQ(records[4].size(), 40u);
  std::vector<std::uint8_t> joined;
  std::size_t pieces = 0;
  tb::join_block_summary_records(
      t.grid, [&](std::size_t i) { return records[i]; },
      [&](std::span<const std::uint8_t> p) { joined.insert(joined.end(), p.begin(), p.end()), ++pieces; });
  EXPECT_EQ(joined, tb::encode_block_summaries(t.grid, sums));
  EXPECT_EQ(pieces, sums.size() + 2);  // header, records, CRC
  std::size_t records_bytes = 0;
  for (const auto& r : records) records_bytes += r.size();
  EXPECT_EQ(joined.size(), tb::kBlockSummariesFraming + records_bytes);
  std::vector<std::uint8_t> longer = records[0];
  longer.push_back(0);
  EXPECT_THROW(tb::decode_block_summary_record(t.grid, 0, longer, "t.db"), tb::DatabaseError);
  const std::vector<std::uint8_t> shorter(records[0].begin(), records[0].end() - 1);
  EXPECT_THROW(tb::decode_block_summary_record(t.grid, 0, shorter, "t.db"), tb::DatabaseError);
  EXPECT_THROW(tb::decode_block_summary_record(t.grid, sums.size(), records[0], "t.db"), tb::DatabaseError);
}

TEST(Standin, Version1BlobDecodesAsTwoTriangleStandins) {
  // A version 1 blob for a 2 x 1 grid of 3 x 3 blocks (a 5 x 3 terrain), written by hand from
  // its documented layout: record = 7 f64 (z00 z10 z01 z11 zmin zmax tm_error), u8 base_is_tm,
  // 7 zero bytes.
  const tb::BlockGrid g(5, 3, 3, pm::GridTransform::identity());
  std::vector<std::uint8_t> b;
  for (std::uint32_t v : {0x53424C54u, 1u, 2u, 1u}) append_le(b, v);  // magic, version, cols, rows
  for (int i = 0; i < 2; ++i) {
    for (double d : {1.0 + i, 2.0, 3.0, 4.0, 0.5, 9.0, 2.5 * (i + 1)}) append_le(b, d);
    b.push_back(std::uint8_t(i));
    b.insert(b.end(), 7, 0);
  }
  append_le(b, std::uint32_t(0));  // the CRC, by reseal
  reseal(b);
  const std::vector<tb::BlockSummary> s = tb::decode_block_summaries(g, b, "old.db");
  ASSERT_EQ(s.size(), 2u);
  EXPECT_EQ(s[1].z00, 2.0);
  EXPECT_EQ(s[1].zmax, 9.0);
  EXPECT_TRUE(s[1].base_is_tm);
  EXPECT_FALSE(s[0].base_is_tm);
  for (int i = 0; i < 2; ++i) {
    EXPECT_EQ(s[std::size_t(i)].standin, tb::StandinKind::TwoTriangles);
    EXPECT_EQ(s[std::size_t(i)].standin_error, 2.5 * (i + 1));
    EXPECT_EQ(s[std::size_t(i)].points,
              (std::vector<tb::StandinPoint>{{0, 0, 1.0 + i}, {2, 0, 2.0}, {0, 2, 3.0}, {2, 2, 4.0}}));
    EXPECT_EQ(s[std::size_t(i)].triangles, (std::vector<std::array<std::uint32_t, 3>>{{0, 1, 3}, {0, 3, 2}}));
    EXPECT_EQ(s[std::size_t(i)].triangle_errors, (std::vector<double>{2.5 * (i + 1), 2.5 * (i + 1)}));
    // The surface is the two-triangle surface (tm_height) everywhere.
    EXPECT_DOUBLE_EQ(tb::standin_height(s[std::size_t(i)], 1.5, 0.5),
                     tb::tm_height(g, g.key(std::size_t(i)), s[std::size_t(i)], 1.5 + 2 * i, 0.5));
  }
  b.pop_back();
  EXPECT_EQ(decode_error(g, b), "t.db: block_summaries: size 147 bytes, expected 148");  // 16 + 2 x 64 + 4
}

TEST(Standin, CorruptBlobsNameTheFileAndTheProblem) {
  const terralod::test::BlockedTerrain t =
      terralod::test::make_blocked_terrain(65, 33, 33, /*seed=*/8, 30.0, 500.0);
  const std::vector<std::uint8_t> good = tb::encode_block_summaries(t.grid, t.summaries);
  ASSERT_EQ(t.summaries[0].standin, tb::StandinKind::Tin);
  std::vector<std::uint8_t> b = good;
  b[60] ^= 4;
  EXPECT_EQ(decode_error(t.grid, b), "t.db: block_summaries: checksum mismatch");
  b = good;
  b.resize(b.size() - 30);
  reseal(b);
  EXPECT_EQ(decode_error(t.grid, b).rfind("t.db: block_summaries: block record 1: truncated", 0), 0u)
      << decode_error(t.grid, b);
  b = good;
  b[4] = 3;
  reseal(b);
  EXPECT_EQ(decode_error(t.grid, b), "t.db: block_summaries: unsupported version 3");
  // Record 0 starts at byte 16; its kind byte is at 16 + 32, its first point at 16 + 40.
  b = good;
  b[16 + 32] = 7;
  reseal(b);
  EXPECT_EQ(decode_error(t.grid, b), "t.db: block_summaries: block record 0: bad kind or flags");
  b = good;
  b[16 + 40] = 0xff;  // first point's col -> far outside the 33-sample block
  b[16 + 41] = 0x7f;
  reseal(b);
  EXPECT_EQ(decode_error(t.grid, b),
            "t.db: block_summaries: block record 0: stand-in point outside the block");
  b = good;
  const std::size_t n = t.summaries[0].points.size();
  b[16 + 40 + 12 * n] = std::uint8_t(n);  // first triangle's first index out of range
  reseal(b);
  EXPECT_EQ(decode_error(t.grid, b),
            "t.db: block_summaries: block record 0: stand-in triangle index out of range");
  b = good;
  std::swap(b[16 + 40 + 12 * n + 1], b[16 + 40 + 12 * n + 2]);  // first triangle turned clockwise
  reseal(b);
  EXPECT_EQ(decode_error(t.grid, b),
            "t.db: block_summaries: block record 0: stand-in triangle not counter-clockwise");
  b = good;
  b.insert(b.end() - 4, 3, 0);
  reseal(b);
  EXPECT_EQ(decode_error(t.grid, b).rfind("t.db: block_summaries: size", 0), 0u) << decode_error(t.grid, b);
}

TEST(Standin, BuildDatabaseWritesTheSummariesBlob) {
  // build_database writes the blob with the tree; it equals what read_block_summaries computes
  // from the blocks (the same stand-in options), so the runtime needs no block read at open.
  const terralod::test::BlockedTerrain t =
      terralod::test::make_blocked_terrain(65, 49, 17, /*seed=*/6, 30.0, 400.0);
  const std::string path = std::string(TERRALOD_TEST_TMP) + "/standins.db";
  for (const char* ext : {"", "-wal", "-shm"}) std::remove((path + ext).c_str());
  tb::DatabaseBuildOptions o;
  o.block_size = 17;
  o.threads = 2;
  o.standin = standin(tb::StandinKind::NonRegularGrid, 20);
  const tb::DatabaseSummary sum = tb::build_database(t.hf, path, o);
  EXPECT_GT(sum.summaries_bytes, 0u);
  EXPECT_EQ(sum.standin, "nonregular");
  EXPECT_LT(sum.mean_standin_error, sum.mean_tm_error);
  tb::BlockDatabase db = tb::BlockDatabase::open(path);
  const auto blob = db.read_blob(tb::kBlockSummariesBlob);
  ASSERT_TRUE(blob);
  EXPECT_EQ(blob->size(), sum.summaries_bytes);
  const std::vector<tb::BlockSummary> stored = tb::read_block_summaries(db, t.grid);
  for (const tb::BlockSummary& s : stored) EXPECT_EQ(s.standin, tb::StandinKind::NonRegularGrid);
  // A copy without the blob (same metadata, same blocks): computed from the blocks, equal.
  const std::string copy = path + ".copy.db";
  for (const char* ext : {"", "-wal", "-shm"}) std::remove((copy + ext).c_str());
  {
    tb::BlockDatabase c = tb::BlockDatabase::create(copy, db.info());
    for (tb::BlockKey k : db.blocks()) c.put_block(k, db.read_block(k));
    EXPECT_FALSE(c.read_blob(tb::kBlockSummariesBlob));
    EXPECT_EQ(tb::read_block_summaries(c, t.grid, {}, o.standin), stored);
    EXPECT_NE(tb::read_block_summaries(c, t.grid), stored);  // the default kind (TIN) differs
  }
  for (const char* ext : {"", "-wal", "-shm"}) std::remove((copy + ext).c_str());
  for (const char* ext : {"", "-wal", "-shm"}) std::remove((path + ext).c_str());
}

TEST(Standin, HostileBytesNeverCrashTheDecoder) {
  // Every truncation, and random byte edits with a valid checksum: DatabaseError naming the
  // file, or a decoded blob whose stand-ins still cover each block with its 4 corners (the
  // runtime relies on that). Run under ASan in CI.
  const std::uint64_t seed = 777;
  std::printf("seed %llu\n", static_cast<unsigned long long>(seed));
  std::mt19937_64 rng(seed);
  const terralod::test::BlockedTerrain t =
      terralod::test::make_blocked_terrain(49, 33, 17, /*seed=*/2, 30.0, 300.0);
  const std::vector<std::uint8_t> good = tb::encode_block_summaries(t.grid, t.summaries);
  std::size_t rejected = 0, accepted = 0;
  auto check = [&](const std::vector<std::uint8_t>& b) {
    try {
      const std::vector<tb::BlockSummary> s = tb::decode_block_summaries(t.grid, b, "h.db");
      ++accepted;
      for (std::size_t i = 0; i < s.size(); ++i) {
        const tb::SampleRect d = t.grid.domain(t.grid.key(i));
        std::int64_t area2 = 0;
        for (const auto& tri : s[i].triangles) {
          for (std::uint32_t v : tri) ASSERT_LT(v, s[i].points.size());
          const tb::StandinPoint &a = s[i].points[tri[0]], &e = s[i].points[tri[1]], &c = s[i].points[tri[2]];
          area2 +=
              std::int64_t(e.col - a.col) * (c.row - a.row) - std::int64_t(e.row - a.row) * (c.col - a.col);
        }
        ASSERT_EQ(area2, 2 * std::int64_t(d.width() - 1) * (d.height() - 1));
        ASSERT_EQ(s[i].triangle_errors.size(), s[i].triangles.size());
      }
    } catch (const tb::DatabaseError& e) {
      ++rejected;
      ASSERT_EQ(std::string(e.what()).rfind("h.db: block_summaries: ", 0), 0u) << e.what();
    }
  };
  for (std::size_t n = 0; n < good.size(); n += 7) {
    std::vector<std::uint8_t> b(good.begin(), good.begin() + std::ptrdiff_t(n));
    if (b.size() >= 4) reseal(b);
    check(b);
  }
  std::uniform_int_distribution<std::size_t> pos(16, good.size() - 5);
  for (int trial = 0; trial < 3000; ++trial) {
    std::vector<std::uint8_t> b = good;
    for (int k = 0; k <= trial % 3; ++k) b[pos(rng)] ^= std::uint8_t(1u << (rng() % 8));
    reseal(b);
    check(b);
  }
  std::printf("%zu rejected, %zu accepted (edits of heights and errors that stay consistent)\n", rejected,
              accepted);
  EXPECT_GT(rejected, 0u);
}
