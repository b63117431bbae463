// The runtime's block summaries with stand-ins read on demand (blocks/src/summary_store.hpp)
// over a real database: every summary it gives equals the blob's, what it holds from opening
// does not grow with the stand-ins, stand-ins go and come back, and a database changed under
// it is never a wrong stand-in (the store keeps its snapshot; opened again, it is an error). Also the
// runtime's side: what it holds at opening, and the stand-ins a flight reads.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "run_command.hpp"
#include "summary_store.hpp"  // private to the runtime
#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/terrain_runtime.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace tb = terralod::blocks;
namespace tp = terralod::pm;
namespace tt = terralod::test;
using tb::detail::SummaryStore;

namespace {

// 513 x 385 samples in blocks of 33: 16 x 12 blocks with 64-point TIN stand-ins, and a void
// over the whole of block (3, 2), which has no stand-in (an empty record). Built once for every
// test of this executable (each runs as a process of its own); the tests only read it, and copy
// it to change it.
std::string database() {
  static const std::string path = tt::shared_file("summary_store.db", [](const std::filesystem::path& p) {
                                    tp::TerrainOptions to;
                                    to.width = 513, to.height = 385, to.seed = 5, to.spacing = 30.0,
                                    to.relief = 900.0;
                                    to.quantize_to_metres = true;
                                    tp::Heightfield hf = tp::generate_terrain(to);
                                    std::vector<std::uint8_t> mask(hf.size(), 1);
                                    for (int r = 64; r <= 96; ++r)
                                      for (int c = 96; c <= 128; ++c)
                                        mask[std::size_t(r) * 513 + std::size_t(c)] = 0;
                                    hf.set_mask(std::move(mask));
                                    tb::DatabaseBuildOptions o;
                                    o.block_size = 33;
                                    o.threads = 2;
                                    tb::build_database(hf, p.string(), o);
                                  }).string();
  return path;
}

std::vector<tb::BlockSummary> decoded(const std::string& path, tb::BlockGrid& grid) {
  const tb::BlockDatabase db = tb::BlockDatabase::open(path);
  grid = tb::BlockGrid::from_info(db.info());
  return tb::decode_block_summaries(grid, *db.read_blob(tb::kBlockSummariesBlob), path);
}

std::size_t surface_bytes(const tb::BlockSummary& s) {
  return tp::capacity_bytes(s.points) + tp::capacity_bytes(s.triangles) +
         tp::capacity_bytes(s.triangle_errors);
}

}  // namespace

TEST(SummaryStore, GivesTheBlobsSummariesAndHoldsOnlyTheirFields) {
  tb::BlockGrid grid;
  const std::vector<tb::BlockSummary> want = decoded(database(), grid);
  ASSERT_EQ(want.size(), 16u * 12u);
  SummaryStore store(database(), grid);
  const std::size_t fixed = store.fixed_bytes();
  std::size_t empty = 0, surfaces = 0;
  for (std::size_t i = 0; i < want.size(); ++i) {
    SCOPED_TRACE("block " + std::to_string(i));
    EXPECT_EQ(store.has_standin(i), !want[i].triangles.empty());
    empty += want[i].empty;
    surfaces += surface_bytes(want[i]);
    // The fields are there before any read.
    const tb::BlockSummary& f = store.fields()[i];
    EXPECT_TRUE(f.points.empty() && f.triangles.empty() && f.triangle_errors.empty());
    EXPECT_EQ(f.zmin, want[i].zmin);
    EXPECT_EQ(f.zmax, want[i].zmax);
    EXPECT_EQ(f.tm_error, want[i].tm_error);
    EXPECT_EQ(f.standin_error, want[i].standin_error);
    EXPECT_EQ(f.z00, want[i].z00);
    EXPECT_EQ(f.z11, want[i].z11);
    EXPECT_EQ(f.standin, want[i].standin);
    EXPECT_EQ(f.base_is_tm, want[i].base_is_tm);
    EXPECT_EQ(f.empty, want[i].empty);
    EXPECT_TRUE(store.summary(i, 1) == want[i]);
  }
  EXPECT_EQ(empty, 1u);
  EXPECT_EQ(store.reads(), want.size() - empty);
  // What opening holds: the fields and a record's place (16 bytes) a block, plus the connection
  // (its page cache limit and SQLite's own), not the stand-ins.
  const std::size_t per_block = sizeof(tb::BlockSummary) + 16;
  EXPECT_LE(fixed, want.size() * per_block + (std::size_t(512) << 10));
  EXPECT_GT(surfaces, 10 * want.size() * per_block) << "the stand-ins are what is not held";
  EXPECT_EQ(store.fixed_bytes(), fixed) << "reading stand-ins does not change what opening holds";
  EXPECT_GE(store.held_bytes(), surfaces);
  EXPECT_EQ(store.held_count(), want.size() - empty);

  // Kept kKeepFrames frames after their last use, then dropped, and read again equal.
  store.summary(7, 50);
  store.trim(1 + SummaryStore::kKeepFrames);
  EXPECT_EQ(store.held_count(), want.size() - empty);
  store.trim(2 + SummaryStore::kKeepFrames);
  EXPECT_EQ(store.held_count(), 1u) << "block 7, used at frame 50, stays";
  EXPECT_LT(store.held_bytes(), surfaces / 50);
  for (std::size_t i = 0; i < want.size(); ++i) EXPECT_TRUE(store.summary(i, 500) == want[i]);
  EXPECT_EQ(store.reads(), 2 * (want.size() - empty) - 1);
}

TEST(SummaryStore, ADatabaseChangedUnderItGivesTheSnapshotThenAnErrorNamingTheFile) {
  const std::string copy = (tt::process_temp_dir("summary_store") / "changed.db").string();
  std::filesystem::copy_file(database(), copy, std::filesystem::copy_options::overwrite_existing);
  tb::BlockGrid grid;
  const std::vector<tb::BlockSummary> want = decoded(copy, grid);
  SummaryStore store(copy, grid);
  ASSERT_TRUE(store.summary(0, 1) == want[0]);
  // Another connection rewrites one byte of the last record's stand-in (the recorded CRC left
  // as it was, as a damaged file would have it).
  {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(copy.c_str(), &db), SQLITE_OK);
    sqlite3_stmt* st = nullptr;
    ASSERT_EQ(
        sqlite3_prepare_v2(db, "SELECT data FROM blobs WHERE name = 'block_summaries'", -1, &st, nullptr),
        SQLITE_OK);
    ASSERT_EQ(sqlite3_step(st), SQLITE_ROW);
    const auto* p = static_cast<const std::uint8_t*>(sqlite3_column_blob(st, 0));
    std::vector<std::uint8_t> bytes(p, p + sqlite3_column_bytes(st, 0));
    sqlite3_finalize(st);
    bytes[bytes.size() - 11] ^= 0x5A;
    ASSERT_EQ(
        sqlite3_prepare_v2(db, "UPDATE blobs SET data = ?1 WHERE name = 'block_summaries'", -1, &st, nullptr),
        SQLITE_OK);
    sqlite3_bind_blob64(st, 1, bytes.data(), bytes.size(), SQLITE_STATIC);
    ASSERT_EQ(sqlite3_step(st), SQLITE_DONE);
    sqlite3_finalize(st);
    sqlite3_close(db);
  }
  // The store reads the database as it was when opened (its blob handle keeps SQLite's WAL
  // snapshot): the same stand-in, not a mixture.
  const std::size_t last = want.size() - 1;
  EXPECT_TRUE(store.summary(last, 2) == want[last]);
  // Opened again, the database-level checksum no longer matches.
  try {
    SummaryStore again(copy, grid);
    FAIL() << "a corrupt blob was opened";
  } catch (const tb::DatabaseError& e) {
    EXPECT_EQ(e.path(), copy);
    EXPECT_NE(std::string(e.what()).find("checksum mismatch"), std::string::npos) << e.what();
  }
}

TEST(SummaryStore, ABlobOfAnotherGridIsAnErrorNamingTheFile) {
  const std::string copy = (tt::process_temp_dir("summary_store") / "other_grid.db").string();
  std::filesystem::copy_file(database(), copy, std::filesystem::copy_options::overwrite_existing);
  tb::BlockGrid grid;
  decoded(copy, grid);
  {  // the header's column count (bytes 8..11) made 17, as another grid's blob would say
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(copy.c_str(), &db), SQLITE_OK);
    ASSERT_EQ(
        sqlite3_exec(
            db,
            "UPDATE blobs SET data = CAST(substr(data, 1, 8) || x'11000000' || substr(data, 13) AS BLOB) "
            "WHERE name = 'block_summaries'",
            nullptr, nullptr, nullptr),
        SQLITE_OK);
    sqlite3_close(db);
  }
  try {
    SummaryStore store(copy, grid);
    FAIL() << "a blob of another grid was opened";
  } catch (const tb::DatabaseError& e) {
    EXPECT_EQ(e.path(), copy);
    EXPECT_NE(std::string(e.what()).find("block grid 17 x 12 does not match the database's 16 x 12"),
              std::string::npos)
        << e.what();
  }
}

TEST(SummaryStore, TheRuntimeHoldsFieldsAtOpeningAndReadsTheStandinsItLooksAt) {
  tb::BlockGrid grid;
  const std::vector<tb::BlockSummary> all = decoded(database(), grid);
  const tb::BlockDatabase db = tb::BlockDatabase::open(database());
  const tb::ApproximationTree tree = tb::decode_tree(*db.read_blob("tree"), database());
  std::size_t surfaces = 0;
  for (const tb::BlockSummary& s : all) surfaces += surface_bytes(s);
  tb::RuntimeOptions o;
  o.morph_seconds = 0;
  o.tolerance_px = 8;  // stand-ins meet tau / 2 over most of the view
  tb::TerrainRuntime rt(database(), o);
  // At opening: the tree, each block's fields, record place and vertex count, one connection.
  const std::size_t opening = rt.stats().resident_bytes;
  EXPECT_LE(opening, tree.memory_bytes() + all.size() * (sizeof(tb::BlockSummary) + 16 + 8) +
                         (std::size_t(512) << 10));
  EXPECT_LT(opening, tree.memory_bytes() + surfaces) << "the stand-ins are not all held";
  // A view from high over the middle: far blocks are drawn as their stand-ins, read now.
  tp::Camera c;
  const auto [x, y] = grid.transform().to_world(256, 192);
  c.x = x, c.y = y, c.z = 6000;
  c.pitch_deg = -30;
  rt.fit_camera(c);
  const tb::RuntimeFrameStats& s = rt.update(tp::View(c), 0.0);
  EXPECT_GT(s.standin_blocks, 0u);
  EXPECT_GE(s.standins_held, s.standin_blocks);
  EXPECT_EQ(s.standin_reads_total, s.standins_held);
  EXPECT_LT(s.standins_held, all.size());
  // Held stand-ins are counted, and the same view reads nothing again.
  const tb::RuntimeFrameStats& t = rt.update(tp::View(c), 1.0 / 60);
  EXPECT_EQ(t.standin_reads_total, s.standins_held);
}
