// Replays every input the fuzz targets ever failed on (fuzz/regressions/<target>/) through the
// targets' own checks, and pins each fix with a hand-made case.
//
// A file in fuzz/regressions/fuzz_pm_decoder/ is fed to fuzz/fuzz_pm_decoder.cpp, one in
// fuzz/regressions/fuzz_dem_reader/ to fuzz/fuzz_dem_reader.cpp (first byte = the case
// selector described there). The targets are compiled into this test with TERRALOD_FUZZ_REPLAY,
// so a broken invariant throws terralod::fuzz::Finding and is reported here as a failure; a
// memory error shows in the sanitizer runs of scripts/test.sh.
//
// Findings so far (scripts/fuzz.sh):
//   fuzz_pm_decoder/nonfinite-transform: a PM whose grid transform holds NaN/inf decoded fine,
//     giving NaN world positions. Fix: decode_pm rejects it ("the grid transform is not
//     finite"), encode_pm refuses to write it.
//   fuzz_pm_decoder/transform-overflows-world-coordinates: a finite transform (xc ~ 1e308)
//     whose world coordinates overflow on the grid made the hierarchy's radii NaN and lose
//     roots. Fix: decode_pm/encode_pm require 2 (|x0| + (W-1)|xc| + (H-1)|xr|) (and y) finite.
//   fuzz_dem_reader/asc-header-declares-huge-grid (found by review while writing the target,
//     kept as a seed of the failure class): a 67-byte Esri ASCII grid declaring 30000 x 30000
//     values made the reader allocate and zero 7.2 GB before finding the data short. Fix: the
//     reader refuses more values than the file has bytes (tests/stress/test_bad_input.cpp).
//   fuzz_block_database/blocks-is-an-endless-recursive-view (found by review while writing the
//     target, kept as a seed of the failure class): a valid database whose 'blocks' table is
//     replaced by a view over an endless recursive CTE would make blocks() run forever. Fix:
//     BlockDatabase::open requires its five tables to be real tables ("schema mismatch:
//     'blocks' is not a table"), tests/blocks/test_block_database.cpp.
//   fuzz_block_summaries/grid-width-near-int-max-overflows-cols: BlockGrid computed
//     ceil((w-1)/(B-1)) as (w - 1 + B - 2) / (B - 1) in int, overflowing (UB) for a grid width
//     near INT_MAX (a database's info may say so). Fix: 64-bit arithmetic.
//   fuzz_block_summaries/v1-corner-height-outside-zmin-zmax: a version 1 blob whose corner
//     heights lie outside [zmin, zmax] decoded, giving stand-in points outside the block's box.
//     Fix: decode_block_summaries rejects it ("a corner outside zmin..zmax").
//   fuzz_block_summaries/v2-huge-grid-allocates-before-size-check: a 20-byte version 2 blob for
//     a grid of 2^32 blocks made the decoder allocate every summary (600 GB) before reading a
//     record. Fix: it first checks the blob can hold the records (>= 40 bytes each, a record's
//     header; the check said 95 until an all-void block's 40-byte record was found refused).
//   fuzz_mesh_reader/* (found by review while writing the target, kept as seeds of the failure
//     classes the readers guard against): an ascii PLY declaring 4e9 vertices and faces in a
//     few bytes (refused before allocating: every ascii value takes >= 2 bytes), a big-endian
//     PLY whose face list counts 2^32 - 1 indices (refused as truncated), and an OBJ face whose
//     relative index -4 points before the first of 3 vertices (refused naming the line).
//   fuzz_json/* (seeds written with the target, kept as the failure classes of the reader):
//     a stored texture layer record and a --rules file (valid), every escape with a lone
//     surrogate, numbers out of range, a trailing comma, a key twice, 64 and 65 nested levels,
//     truncated input.
//   fuzz_object_rules/* (seeds, kept as the rules' edge cases): the header's distance example
//     with every optional key, screen-size ranges, a none range before a drawing one, limits
//     near the largest double, and the smallest positive limit beside a fractional quad count.
#include <gtest/gtest.h>
#include <zlib.h>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include "build_threads.hpp"
#include "fuzz_support.hpp"
#include "terralod/blocks/active_region.hpp"
#include "terralod/pm/pm_io.hpp"
#include "terralod/pm/progressive_mesh.hpp"
#include "terralod/pm/terrain_generator.hpp"

extern "C" int terralod_fuzz_pm_decoder(const std::uint8_t* data, std::size_t size);
extern "C" int terralod_fuzz_dem_reader(const std::uint8_t* data, std::size_t size);
extern "C" int terralod_fuzz_camera_path(const std::uint8_t* data, std::size_t size);
extern "C" int terralod_fuzz_block_database(const std::uint8_t* data, std::size_t size);
extern "C" int terralod_fuzz_tree_decoder(const std::uint8_t* data, std::size_t size);
extern "C" int terralod_fuzz_block_summaries(const std::uint8_t* data, std::size_t size);
extern "C" int terralod_fuzz_dem_reader_init(int* argc, char*** argv);
extern "C" int terralod_fuzz_mesh_reader(const std::uint8_t* data, std::size_t size);
extern "C" int terralod_fuzz_mesh_reader_init(int* argc, char*** argv);
extern "C" int terralod_fuzz_json(const std::uint8_t* data, std::size_t size);
extern "C" int terralod_fuzz_object_rules(const std::uint8_t* data, std::size_t size);

namespace {

namespace fs = std::filesystem;
namespace pm = terralod::pm;

std::vector<std::uint8_t> read_all(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::vector<std::uint8_t>(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

/// Replays every file of fuzz/regressions/<target>/; returns how many there were.
std::size_t replay(const std::string& target, int (*one)(const std::uint8_t*, std::size_t)) {
  const fs::path dir = fs::path(TERRALOD_FUZZ_REGRESSIONS) / target;
  std::vector<fs::path> files;
  if (fs::is_directory(dir))
    for (const auto& e : fs::directory_iterator(dir))
      if (e.is_regular_file() && e.path().filename().string()[0] != '.') files.push_back(e.path());
  std::sort(files.begin(), files.end());
  for (const fs::path& f : files) {
    SCOPED_TRACE(f.string());
    const std::vector<std::uint8_t> bytes = read_all(f);
    try {
      (void)one(bytes.data(), bytes.size());
    } catch (const terralod::fuzz::Finding& e) {
      ADD_FAILURE() << f.filename() << ": " << e.what;
    } catch (const std::exception& e) {
      ADD_FAILURE() << f.filename() << ": unexpected exception: " << e.what();
    }
  }
  std::printf("  %s: replayed %zu inputs from %s\n", target.c_str(), files.size(), dir.c_str());
  return files.size();
}

TEST(FuzzRegressions, PmDecoder) { EXPECT_GE(replay("fuzz_pm_decoder", terralod_fuzz_pm_decoder), 2u); }

TEST(FuzzRegressions, CameraPath) { EXPECT_GE(replay("fuzz_camera_path", terralod_fuzz_camera_path), 3u); }

TEST(FuzzRegressions, BlockDatabase) {
  EXPECT_GE(replay("fuzz_block_database", terralod_fuzz_block_database), 1u);
}

TEST(FuzzRegressions, TreeDecoder) { EXPECT_GE(replay("fuzz_tree_decoder", terralod_fuzz_tree_decoder), 2u); }

TEST(FuzzRegressions, BlockSummaries) {
  EXPECT_GE(replay("fuzz_block_summaries", terralod_fuzz_block_summaries), 3u);
}

TEST(FuzzRegressions, MeshReader) {
  int argc = 0;
  char** argv = nullptr;
  terralod_fuzz_mesh_reader_init(&argc, &argv);
  EXPECT_GE(replay("fuzz_mesh_reader", terralod_fuzz_mesh_reader), 3u);
}

TEST(FuzzRegressions, Json) { EXPECT_GE(replay("fuzz_json", terralod_fuzz_json), 9u); }

TEST(FuzzRegressions, ObjectRules) { EXPECT_GE(replay("fuzz_object_rules", terralod_fuzz_object_rules), 4u); }

TEST(FuzzRegressions, DemReader) {
  int argc = 0;
  char** argv = nullptr;
  terralod_fuzz_dem_reader_init(&argc, &argv);
  replay("fuzz_dem_reader", terralod_fuzz_dem_reader);
}

// ------------------------------------------------------------------------------------------
// Hand-made cases for the fixes.

pm::ProgressiveMesh small_pm() {
  pm::TerrainOptions o;
  o.width = 9, o.height = 9, o.seed = 5, o.quantize_to_metres = true;
  return pm::ProgressiveMesh::build(pm::generate_terrain(o), terralod::test::build_threads(1));
}

/// Encoded PM with the grid transform's six doubles (offset 28, see pm_io.cpp) replaced and
/// the checksum recomputed, as a hostile writer would.
std::vector<std::uint8_t> with_transform(const pm::GridTransform& t) {
  std::vector<std::uint8_t> b = pm::encode_pm(small_pm());
  const double v[6] = {t.x0, t.xc, t.xr, t.y0, t.yc, t.yr};
  for (int k = 0; k < 6; ++k) {
    const auto bits = std::bit_cast<std::uint64_t>(v[k]);
    for (int i = 0; i < 8; ++i) b[28 + 8 * std::size_t(k) + std::size_t(i)] = std::uint8_t(bits >> (8 * i));
  }
  const auto crc = std::uint32_t(crc32(0L, b.data(), uInt(b.size() - 4)));
  for (int i = 0; i < 4; ++i) b[b.size() - 4 + std::size_t(i)] = std::uint8_t(crc >> (8 * i));
  return b;
}

std::string decode_error(const std::vector<std::uint8_t>& b) {
  try {
    (void)pm::decode_pm(b, "forged.pm");
  } catch (const pm::PmFormatError& e) {
    return e.what();
  }
  return "(decoded)";
}

TEST(FuzzRegressions, NonFiniteGridTransformIsRejected) {
  constexpr double nan = std::numeric_limits<double>::quiet_NaN(),
                   inf = std::numeric_limits<double>::infinity();
  for (const pm::GridTransform& t :
       {pm::GridTransform{nan, 1, 0, 0, 0, -1}, pm::GridTransform{0, inf, 0, 0, 0, -1},
        pm::GridTransform{0, 1, 0, 0, 0, -inf}}) {
    EXPECT_EQ(decode_error(with_transform(t)), "forged.pm: corrupt header: the grid transform is not finite");
    pm::ProgressiveMesh p = small_pm();
    pm::Heightfield hf = p.heightfield();
    hf.transform = t;
    const pm::ProgressiveMesh q =
        pm::ProgressiveMesh::from_parts(hf, p.metric(), p.error_quantum(), p.collapses(), p.dropped_faces());
    EXPECT_THROW((void)pm::encode_pm(q), std::invalid_argument);
  }
  // Control: the same forgery with an ordinary transform decodes.
  EXPECT_EQ(decode_error(with_transform(pm::GridTransform::north_up(500000, 5000000, 0.01, 0.01))),
            "(decoded)");
}

TEST(FuzzRegressions, TransformWhoseWorldCoordinatesOverflowIsRejected) {
  // 1e308 per column: column 8 would be at 8e308 = inf.
  const std::string msg = decode_error(with_transform(pm::GridTransform{0, 1e308, 0, 0, 0, -1}));
  EXPECT_EQ(msg,
            "forged.pm: corrupt header: the grid transform maps samples to non-finite world coordinates");
  // Differences must stay finite too: |x| up to 1.2e308 at both ends of the grid.
  EXPECT_NE(decode_error(with_transform(pm::GridTransform{-1.2e308, 3e307, 0, 0, 0, -1})), "(decoded)");
  // The largest sane planetary coordinates are far inside the limit.
  EXPECT_EQ(decode_error(with_transform(pm::GridTransform{-4e7, 1e6, 0, 4e7, 0, -1e6})), "(decoded)");
}

// "block_summaries" blob: header (magic, version, cols, rows), `records`, CRC-32 trailer.
std::vector<std::uint8_t> summaries_blob(std::uint32_t version, std::uint32_t cols, std::uint32_t rows,
                                         const std::vector<double>& records) {
  std::vector<std::uint8_t> b;
  auto u32 = [&](std::uint32_t v) {
    for (int i = 0; i < 4; ++i) b.push_back(std::uint8_t(v >> (8 * i)));
  };
  for (std::uint32_t v : {0x53424C54u, version, cols, rows}) u32(v);
  for (double d : records) {
    const auto bits = std::bit_cast<std::uint64_t>(d);
    for (int i = 0; i < 8; ++i) b.push_back(std::uint8_t(bits >> (8 * i)));
  }
  u32(std::uint32_t(crc32(0L, b.data(), uInt(b.size()))));
  return b;
}

std::string summaries_error(const terralod::blocks::BlockGrid& g, const std::vector<std::uint8_t>& b) {
  try {
    (void)terralod::blocks::decode_block_summaries(g, b, "t.db");
  } catch (const terralod::blocks::DatabaseError& e) {
    return e.what();
  }
  return "(decoded)";
}

TEST(FuzzRegressions, BlockGridNearIntMax) {
  // ceil((2^31 - 2) / 8) = 2^28 block columns; ceil(1 / 8) = 1 row.
  const terralod::blocks::BlockGrid g(std::numeric_limits<int>::max(), 2, 9, pm::GridTransform::identity());
  EXPECT_EQ(g.cols(), 1 << 28);
  EXPECT_EQ(g.rows(), 1);
  const terralod::blocks::BlockGrid h(2, std::numeric_limits<int>::max(), std::numeric_limits<int>::max(),
                                      pm::GridTransform::identity());
  EXPECT_EQ(h.cols(), 1);
  EXPECT_EQ(h.rows(), 1);
}

TEST(FuzzRegressions, SummariesV1CornerOutsideHeightRangeIsRejected) {
  // 5 x 3 samples in 3-sample blocks: 2 x 1 blocks. Record: z00 z10 z01 z11 zmin zmax tm_error,
  // then base_is_tm and 7 zero bytes (one f64 0).
  const terralod::blocks::BlockGrid g(5, 3, 3, pm::GridTransform::identity());
  const std::vector<double> good{1, 2, 3, 4, 0, 9, 0.5, 0};
  std::vector<double> recs = good;
  recs.insert(recs.end(), good.begin(), good.end());
  EXPECT_EQ(summaries_error(g, summaries_blob(1, 2, 1, recs)), "(decoded)");
  recs[8 + 3] = 9.5;  // block 1's z11 above its zmax 9
  EXPECT_EQ(summaries_error(g, summaries_blob(1, 2, 1, recs)),
            "t.db: block_summaries: block record 1: a corner outside zmin..zmax");
  recs[8 + 3] = 4, recs[0] = -0.25;  // block 0's z00 below its zmin 0
  EXPECT_EQ(summaries_error(g, summaries_blob(1, 2, 1, recs)),
            "t.db: block_summaries: block record 0: a corner outside zmin..zmax");
}

TEST(FuzzRegressions, SummariesV2TooShortForTheGridIsRejectedBeforeAllocating) {
  // 2^20 + 1 by 2^10 + 1 samples in 3-sample blocks: 2^19 x 2^9 = 2^28 blocks (36 GB of
  // summaries); a v2 record takes >= 40 bytes (an empty block's is its header alone), a 20-byte
  // blob holds none.
  const terralod::blocks::BlockGrid g((1 << 20) + 1, (1 << 10) + 1, 3, pm::GridTransform::identity());
  EXPECT_EQ(summaries_error(g, summaries_blob(2, 1u << 19, 1u << 9, {})),
            "t.db: block_summaries: size 20 bytes, too small for 268435456 block records");
  // 2 blocks need >= 20 + 2 x 40 = 100 bytes: 16 + 9 x 8 + 4 = 92 are too few, whatever
  // they hold; 16 + 10 x 8 + 4 = 100 pass this check and fail on the first record (all zero:
  // 0 stand-in points), as do 16 + 24 x 8 + 4 = 212.
  const terralod::blocks::BlockGrid two(5, 3, 3, pm::GridTransform::identity());
  EXPECT_EQ(summaries_error(two, summaries_blob(2, 2, 1, std::vector<double>(9, 0.0))),
            "t.db: block_summaries: size 92 bytes, too small for 2 block records");
  for (std::size_t n : {10, 24})
    EXPECT_EQ(summaries_error(two, summaries_blob(2, 2, 1, std::vector<double>(n, 0.0))),
              "t.db: block_summaries: block record 0: truncated stand-in");
}

}  // namespace
