// Tests for blocks::BlockDatabase: round trip of everything, bad and corrupted files, checksums,
// transactions, concurrent readers beside a writer, and SIGKILL crash consistency.
#include <gtest/gtest.h>
#include <signal.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "hot_journal.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/pm/byte_io.hpp"

namespace {

namespace fs = std::filesystem;
namespace tb = terralod::blocks;
using Bytes = std::vector<std::uint8_t>;
using tb::BlockDatabase;
using tb::BlockKey;
using tb::DatabaseError;

/// A fresh, empty folder for one test (removed first if a previous run left it).
fs::path fresh_dir(const std::string& name) {
  const fs::path dir =
      fs::path(TERRALOD_TEST_TMP) / ("block_database_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

/// Deterministic bytes of a given size for a seed (splitmix64 stream).
Bytes pattern(std::uint64_t seed, std::size_t size) {
  Bytes b(size);
  std::uint64_t x = seed * 0x9E3779B97F4A7C15ull + 1;
  for (std::size_t i = 0; i < size; ++i) {
    if (i % 8 == 0) {
      x += 0x9E3779B97F4A7C15ull;
      std::uint64_t z = x;
      z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
      z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
      x = z ^ (z >> 31);
    }
    b[i] = std::uint8_t(x >> (8 * (i % 8)));
  }
  return b;
}

std::uint64_t key_seed(BlockKey k) {
  return std::uint64_t(std::uint32_t(k.col)) << 32 | std::uint32_t(k.row);
}

tb::DatabaseInfo sample_info() {
  tb::DatabaseInfo info;
  info.kind = "hybrid";
  info.grid_width = 1201;
  info.grid_height = 977;
  // Values that a decimal round trip or SQLite's REAL storage would not keep bit for bit.
  info.transform = terralod::pm::GridTransform{500000.1 / 3.0,
                                               30.000000000000004,
                                               -0.0,
                                               5000000.0 + 1.0 / 7.0,
                                               std::numeric_limits<double>::denorm_min(),
                                               -30.0};
  info.crs_wkt = "PROJCS[\"WGS 84 / UTM zone 18N\",GEOGCS[\"WGS 84\"]] — ünïcode";
  info.block_size = 257;
  info.build_parameters = R"({"block_size":257,"strategy":"tin","threads":2})";
  info.source = "/data/N44W072.hgt";
  return info;
}

bool same_bits(const terralod::pm::GridTransform& a, const terralod::pm::GridTransform& b) {
  const double va[6] = {a.x0, a.xc, a.xr, a.y0, a.yc, a.yr}, vb[6] = {b.x0, b.xc, b.xr, b.y0, b.yc, b.yr};
  for (int i = 0; i < 6; ++i)
    if (std::bit_cast<std::uint64_t>(va[i]) != std::bit_cast<std::uint64_t>(vb[i])) return false;
  return true;
}

/// The message of the DatabaseError `f` throws ("(no error)" if none).
template <class F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const DatabaseError& e) {
    return e.what();
  }
  return "(no error)";
}

/// Runs SQL on the file directly, bypassing the library (as a hostile or buggy tool would).
void raw_sql(const fs::path& path, const std::string& sql) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  char* err = nullptr;
  const int rc = sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &err);
  const std::string msg = err ? err : "";
  sqlite3_free(err);
  sqlite3_close(db);
  ASSERT_EQ(rc, SQLITE_OK) << sql << ": " << msg;
}

/// Runs an UPDATE with one blob parameter (?1) on the file directly.
void raw_update_blob(const fs::path& path, const std::string& sql, const Bytes& blob) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  sqlite3_stmt* st = nullptr;
  ASSERT_EQ(sqlite3_prepare_v2(db, sql.c_str(), -1, &st, nullptr), SQLITE_OK) << sqlite3_errmsg(db);
  sqlite3_bind_blob(st, 1, blob.data(), int(blob.size()), SQLITE_TRANSIENT);
  EXPECT_EQ(sqlite3_step(st), SQLITE_DONE) << sqlite3_errmsg(db);
  EXPECT_EQ(sqlite3_changes(db), 1);
  sqlite3_finalize(st);
  sqlite3_close(db);
}

void write_file(const fs::path& p, const Bytes& b) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(b.data()), std::streamsize(b.size()));
}

/// A database with a 4 x 3 grid of blocks of 1..12 KB, one named blob, two tiles, one meta.
fs::path small_database(const fs::path& dir) {
  const fs::path path = dir / "terrain.db";
  auto db = BlockDatabase::create(path, sample_info());
  BlockDatabase::Transaction t(db);
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 3; ++r)
      db.put_block({c, r}, pattern(key_seed({c, r}), std::size_t(1024 * (1 + c * 3 + r))));
  db.put_blob("tree", pattern(77, 5000));
  db.put_texture_tile("ortho", 5, 2, pattern(78, 3000));
  db.put_texture_tile("ortho", 6, 2, pattern(79, 3001));
  db.set_meta("build_complete", "1");
  t.commit();
  return path;
}

// ------------------------------------------------------------------------------------------

TEST(BlockDatabase, RoundTripOfEverything) {
  const fs::path dir = fresh_dir("roundtrip");
  const std::string path = (dir / "terrain.db").string();
  const tb::DatabaseInfo info = sample_info();
  // Keys written out of order, including negative ones; sorted order is (col, then row).
  const std::vector<BlockKey> keys = {
      {2, 0}, {0, 1}, {-3, 7}, {0, 0}, {1, 5}, {1, -2}, {2147483647, -2147483647 - 1}};
  {
    auto db = BlockDatabase::create(path, info);
    EXPECT_EQ(db.path(), path);
    EXPECT_EQ(db.info(), info);
    EXPECT_EQ(db.format_version(), BlockDatabase::kFormatVersion);
    for (BlockKey k : keys) db.put_block(k, pattern(key_seed(k), 100 + std::size_t(k.col & 0xff) * 7));
    // Overwrite: the second put replaces the first, with a different size.
    db.put_block({0, 1}, pattern(999, 12345));
    db.put_block({1, 5}, Bytes{});  // an empty blob is a blob
    db.put_blob("tree", pattern(1, 70000));
    db.put_blob("hybrid", pattern(2, 1));
    db.put_blob("tree", pattern(3, 4321));  // replaces
    db.put_texture_tile("relief", 0, 0, pattern(4, 256));
    db.put_texture_tile("ortho", 9000000000LL, 3, pattern(5, 999));
    db.put_texture_tile("ortho", -1, 0, pattern(6, 17));
    db.put_texture_tile("ortho", -1, 0, pattern(7, 18));  // replaces
    db.set_meta("build_complete", "0");
    db.set_meta("layer:ortho", R"({"format":"png"})");
    db.set_meta("build_complete", "1");  // replaces
  }
  const auto db = BlockDatabase::open(path);  // ReadOnly
  EXPECT_EQ(db.mode(), BlockDatabase::Mode::ReadOnly);
  const tb::DatabaseInfo& got = db.info();
  EXPECT_EQ(got.kind, info.kind);
  EXPECT_EQ(got.grid_width, 1201);
  EXPECT_EQ(got.grid_height, 977);
  EXPECT_TRUE(same_bits(got.transform, info.transform));
  EXPECT_TRUE(std::signbit(got.transform.xr));  // -0.0 survives
  EXPECT_EQ(got.transform.yc, std::numeric_limits<double>::denorm_min());
  EXPECT_EQ(got.crs_wkt, info.crs_wkt);
  EXPECT_EQ(got.block_size, 257);
  EXPECT_EQ(got.build_parameters, info.build_parameters);
  EXPECT_EQ(got.source, info.source);
  EXPECT_EQ(db.format_version(), 1);

  std::vector<BlockKey> sorted = keys;
  std::sort(sorted.begin(), sorted.end());
  EXPECT_EQ(db.blocks(), sorted);
  EXPECT_EQ(db.blocks().front(), (BlockKey{-3, 7}));
  for (BlockKey k : keys) {
    SCOPED_TRACE(std::to_string(k.col) + "," + std::to_string(k.row));
    EXPECT_TRUE(db.has_block(k));
    Bytes expect = pattern(key_seed(k), 100 + std::size_t(k.col & 0xff) * 7);
    if (k == BlockKey{0, 1}) expect = pattern(999, 12345);
    if (k == BlockKey{1, 5}) expect.clear();
    EXPECT_EQ(db.read_block(k), expect);
  }
  EXPECT_FALSE(db.has_block({9, 9}));
  EXPECT_EQ(error_of([&] { (void)db.read_block({9, 9}); }), path + ": block (9,9): not in the database");

  EXPECT_EQ(db.read_blob("tree"), pattern(3, 4321));
  EXPECT_EQ(db.read_blob("hybrid"), pattern(2, 1));
  EXPECT_EQ(db.read_blob("nothing"), std::nullopt);
  EXPECT_EQ(db.blob_names(), (std::vector<std::string>{"hybrid", "tree"}));

  EXPECT_EQ(db.texture_layers(), (std::vector<std::string>{"ortho", "relief"}));
  EXPECT_EQ(db.texture_tiles("ortho"), (std::vector<tb::TextureTileKey>{{-1, 0}, {9000000000LL, 3}}));
  EXPECT_EQ(db.texture_tiles("none"), std::vector<tb::TextureTileKey>{});
  EXPECT_EQ(db.read_texture_tile("ortho", -1, 0), pattern(7, 18));
  EXPECT_EQ(db.read_texture_tile("ortho", 9000000000LL, 3), pattern(5, 999));
  EXPECT_EQ(db.read_texture_tile("relief", 0, 0), pattern(4, 256));
  EXPECT_EQ(db.read_texture_tile("relief", 0, 1), std::nullopt);

  EXPECT_EQ(db.get_meta("build_complete"), "1");
  EXPECT_EQ(db.get_meta("layer:ortho"), R"({"format":"png"})");
  EXPECT_EQ(db.get_meta("missing"), std::nullopt);
  EXPECT_EQ(db.meta_keys(), (std::vector<std::string>{"build_complete", "layer:ortho"}));

  const auto report = db.check_integrity();
  EXPECT_TRUE(report.ok);
  EXPECT_TRUE(report.problems.empty());
  EXPECT_EQ(report.items_checked, keys.size() + 2 + 3);  // blocks + named blobs + tiles
}

TEST(BlockDatabase, CreateRefusesAnExistingPathAndLeavesItAlone) {
  const fs::path dir = fresh_dir("create_existing");
  const fs::path path = dir / "existing.db";
  write_file(path, pattern(1, 10));
  EXPECT_EQ(error_of([&] { (void)BlockDatabase::create(path, sample_info()); }),
            path.string() + ": already exists (create() makes a new database only)");
  EXPECT_EQ(fs::file_size(path), 10u);
  // An existing database is not overwritten either.
  const fs::path good = small_database(dir);
  EXPECT_NE(error_of([&] { (void)BlockDatabase::create(good, sample_info()); }).find("already exists"),
            std::string::npos);
  EXPECT_EQ(BlockDatabase::open(good).blocks().size(), 12u);
  // A transform with NaN is refused before anything is written.
  tb::DatabaseInfo nan_info = sample_info();
  nan_info.transform.xc = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(error_of([&] { (void)BlockDatabase::create(dir / "nan.db", nan_info); }),
            (dir / "nan.db").string() + ": cannot create: the grid transform is not finite");
  EXPECT_FALSE(fs::exists(dir / "nan.db"));
  // A folder that does not exist: an error naming the file, and nothing left behind.
  const fs::path nowhere = dir / "no" / "such" / "folder.db";
  EXPECT_EQ(error_of([&] { (void)BlockDatabase::create(nowhere, sample_info()); }),
            nowhere.string() + ": cannot create (No such file or directory)");
}

// is_interrupted_create() is true exactly for what a killed create() leaves (an empty file, or
// a hot rollback journal over a file that was empty), and false for anything that holds data:
// a build deletes what it calls true.
TEST(BlockDatabase, InterruptedCreateIsRecognisedAndNothingElse) {
  const fs::path dir = fresh_dir("interrupted_create");
  const auto open_error = [](const fs::path& p) {
    return error_of([&] { (void)BlockDatabase::open(p.string(), BlockDatabase::Mode::ReadOnly); });
  };
  EXPECT_FALSE(BlockDatabase::is_interrupted_create((dir / "missing.db").string()));
  EXPECT_FALSE(BlockDatabase::is_interrupted_create(dir.string()));
  write_file(dir / "empty.db", {});
  EXPECT_TRUE(BlockDatabase::is_interrupted_create((dir / "empty.db").string()));

  // Killed while switching the new file to WAL mode: a hot journal that restores 0 pages.
  const std::string hot_empty = (dir / "hot_empty.db").string();
  terralod::test::leave_hot_journal(hot_empty, "");
  EXPECT_GT(fs::file_size(hot_empty), 0u);  // the spilled pages are in the file
  EXPECT_TRUE(BlockDatabase::is_interrupted_create(hot_empty));
  EXPECT_EQ(open_error(hot_empty), hot_empty + ": not a terralod database (interrupted create?)");
  EXPECT_GT(fs::file_size(hot_empty + "-journal"), 0u) << "reading must not roll the journal back";

  // A foreign file killed inside a transaction: its journal restores data, so it is not ours.
  const std::string hot_foreign = (dir / "hot_foreign.db").string();
  terralod::test::leave_hot_journal(hot_foreign,
                                    "CREATE TABLE places(name TEXT); INSERT INTO places VALUES ('x')");
  EXPECT_FALSE(BlockDatabase::is_interrupted_create(hot_foreign));
  EXPECT_EQ(open_error(hot_foreign), hot_foreign + ": has a hot rollback journal (not a terralod database)");
  EXPECT_GT(fs::file_size(hot_foreign + "-journal"), 0u);

  raw_sql(dir / "foreign.db", "CREATE TABLE places(name TEXT)");
  EXPECT_FALSE(BlockDatabase::is_interrupted_create((dir / "foreign.db").string()));
  write_file(dir / "garbage.db", pattern(42, 8192));
  EXPECT_FALSE(BlockDatabase::is_interrupted_create((dir / "garbage.db").string()));
  const std::string complete = (dir / "complete.db").string();
  (void)BlockDatabase::create(complete, sample_info());
  EXPECT_FALSE(BlockDatabase::is_interrupted_create(complete));
}

TEST(BlockDatabase, OpenRejectsFilesThatAreNotTerralodDatabases) {
  const fs::path dir = fresh_dir("open_bad");
  const auto open_error = [](const fs::path& p) {
    return error_of([&] { (void)BlockDatabase::open(p.string(), BlockDatabase::Mode::ReadOnly); });
  };
  // Missing file and a folder.
  EXPECT_EQ(open_error(dir / "missing.db"), (dir / "missing.db").string() + ": no such file");
  EXPECT_EQ(open_error(dir), dir.string() + ": is a directory, not a database");
  // Empty file: what a create() killed before its first commit leaves.
  write_file(dir / "empty.db", {});
  EXPECT_EQ(open_error(dir / "empty.db"),
            (dir / "empty.db").string() + ": not a terralod database (interrupted create?)");
  // Garbage bytes.
  write_file(dir / "garbage.db", pattern(42, 8192));
  EXPECT_EQ(open_error(dir / "garbage.db"),
            (dir / "garbage.db").string() + ": not a SQLite database (not a terralod database)");
  // Short garbage (shorter than an SQLite header).
  write_file(dir / "short.db", pattern(43, 50));
  EXPECT_EQ(open_error(dir / "short.db").rfind((dir / "short.db").string() + ": ", 0), 0u);
  // Another SQLite file.
  raw_sql(dir / "foreign.db", "CREATE TABLE places(name TEXT); INSERT INTO places VALUES ('x')");
  EXPECT_EQ(open_error(dir / "foreign.db"),
            (dir / "foreign.db").string() + ": not a terralod database (an SQLite file of another kind)");
  raw_sql(dir / "other_app.db", "PRAGMA application_id = 1234; CREATE TABLE t(x)");
  EXPECT_EQ(open_error(dir / "other_app.db"),
            (dir / "other_app.db").string() + ": not a terralod database (application_id 0x000004d2)");

  // A newer format version.
  const fs::path newer = dir / "newer" / "terrain.db";
  fs::create_directories(newer.parent_path());
  (void)BlockDatabase::create(newer, sample_info());
  raw_sql(newer, "UPDATE info SET format_version = 2");
  EXPECT_EQ(
      open_error(newer),
      newer.string() + ": format version 2 is newer than this terralod reads (1); use a newer terralod");

  // Tampered info (its own checksum), a missing table, a table replaced by a view, missing columns.
  const auto variant = [&](const std::string& name, const std::string& sql) {
    const fs::path p = dir / name / "terrain.db";
    fs::create_directories(p.parent_path());
    (void)BlockDatabase::create(p, sample_info());
    raw_sql(p, sql);
    return open_error(p).substr(p.string().size());
  };
  EXPECT_EQ(variant("info_tampered", "UPDATE info SET grid_width = 1200"), ": info: checksum mismatch");
  EXPECT_EQ(variant("no_meta", "DROP TABLE meta"), ": schema mismatch: no table 'meta'");
  EXPECT_EQ(
      variant(
          "view",
          "DROP TABLE blobs; CREATE VIEW blobs AS SELECT 'n' AS name, 0 AS size, 0 AS crc32, x'' AS data"),
      ": schema mismatch: 'blobs' is not a table");
  EXPECT_EQ(variant("columns", "DROP TABLE blobs; CREATE TABLE blobs(name TEXT, size INTEGER)"),
            ": schema mismatch in table 'blobs' (no such column: crc32)");
  EXPECT_EQ(variant("no_info_row", "DELETE FROM info"), ": corrupt info table (no row)");
  EXPECT_EQ(variant("bad_transform", "UPDATE info SET transform = x'00'"),
            ": corrupt info table (the transform is not 48 bytes)");
}

TEST(BlockDatabase, TruncatedFilesGiveErrorsNamingTheFile) {
  const fs::path dir = fresh_dir("truncated");
  const fs::path good = small_database(dir);  // closed: checkpointed into the main file
  ASSERT_FALSE(fs::exists(good.string() + "-wal"));
  const std::uintmax_t size = fs::file_size(good);
  ASSERT_GT(size, 40000u);
  // Cut at many points: open() throws an error naming the file, or check_integrity() fails
  // (problems naming the file) and every block reads its right bytes or throws such an error;
  // never a crash, never wrong bytes.
  for (std::uintmax_t cut : {std::uintmax_t(0), std::uintmax_t(10), std::uintmax_t(100), std::uintmax_t(4096),
                             std::uintmax_t(5000), size / 3, size / 2, size - 4096, size - 1}) {
    SCOPED_TRACE("cut at " + std::to_string(cut) + " of " + std::to_string(size));
    const fs::path p = dir / ("cut_" + std::to_string(cut) + ".db");
    fs::copy_file(good, p);
    fs::resize_file(p, cut);
    try {
      const auto db = BlockDatabase::open(p.string());
      const auto report = db.check_integrity();
      EXPECT_FALSE(report.ok);
      for (const std::string& problem : report.problems)
        EXPECT_EQ(problem.rfind(p.string() + ": ", 0), 0u) << problem;
      for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 3; ++r) try {
            EXPECT_EQ(db.read_block({c, r}), pattern(key_seed({c, r}), std::size_t(1024 * (1 + c * 3 + r))));
          } catch (const DatabaseError& e) {
            EXPECT_EQ(std::string(e.what()).rfind(p.string() + ": ", 0), 0u) << e.what();
          }
    } catch (const DatabaseError& e) {
      EXPECT_EQ(std::string(e.what()).rfind(p.string() + ": ", 0), 0u) << e.what();
    }
  }
}

TEST(BlockDatabase, CorruptedBlobIsReportedWithTheItemItBelongsTo) {
  const fs::path dir = fresh_dir("corrupt");
  const fs::path path = small_database(dir);
  const std::string p = path.string();
  // Flip one bit of byte 100 of block (3,1) (same length), behind the library's back.
  Bytes flipped = pattern(key_seed({3, 1}), 1024 * 11);
  flipped[100] ^= 0x01;
  raw_update_blob(path, "UPDATE blocks SET data = ?1 WHERE col = 3 AND row = 1", flipped);
  // Truncate block (0,2) to 10 bytes; corrupt the named blob and a tile.
  raw_sql(path, "UPDATE blocks SET data = substr(data, 1, 10) WHERE col = 0 AND row = 2");
  raw_sql(path, "UPDATE blobs SET crc32 = (crc32 + 1) % 4294967296 WHERE name = 'tree'");
  raw_sql(path, "UPDATE texture_tiles SET size = size + 5 WHERE node = 6");

  const auto db = BlockDatabase::open(p);
  EXPECT_EQ(error_of([&] { (void)db.read_block({3, 1}); }), p + ": block (3,1): checksum mismatch");
  EXPECT_EQ(error_of([&] {
              (void)db.read_block({0, 2});
            }),
            p + ": block (0,2): truncated (10 of 3072 bytes)");
  EXPECT_EQ(error_of([&] { (void)db.read_blob("tree"); }), p + ": blob 'tree': checksum mismatch");
  EXPECT_EQ(error_of([&] { (void)db.read_texture_tile("ortho", 6, 2); }),
            p + ": texture tile (layer 'ortho', node 6, level 2): truncated (3001 of 3006 bytes)");
  // The reader goes on: every other item still reads back exactly.
  EXPECT_EQ(db.read_block({3, 0}), pattern(key_seed({3, 0}), 1024 * 10));
  EXPECT_EQ(db.read_texture_tile("ortho", 5, 2), pattern(78, 3000));
  EXPECT_EQ(db.blocks().size(), 12u);

  const auto report = db.check_integrity();
  EXPECT_FALSE(report.ok);
  EXPECT_EQ(report.items_checked, 12u + 1u + 2u);
  EXPECT_EQ(report.problems,
            (std::vector<std::string>{
                p + ": block (0,2): truncated (10 of 3072 bytes)",
                p + ": block (3,1): checksum mismatch",
                p + ": blob 'tree': checksum mismatch",
                p + ": texture tile (layer 'ortho', node 6, level 2): truncated (3001 of 3006 bytes)",
            }));
  // Repair by overwriting: the block reads again and the report shrinks.
  {
    auto rw = BlockDatabase::open(p, BlockDatabase::Mode::ReadWrite);
    rw.put_block({3, 1}, pattern(key_seed({3, 1}), 1024 * 11));
  }
  EXPECT_EQ(db.read_block({3, 1}), pattern(key_seed({3, 1}), 1024 * 11));
  EXPECT_EQ(db.check_integrity().problems.size(), 3u);
}

TEST(BlockDatabase, PageLevelCorruptionIsReportedNotCrashed) {
  const fs::path dir = fresh_dir("pages");
  const fs::path good = small_database(dir);
  const std::uintmax_t size = fs::file_size(good);
  std::mt19937 rng(20261122);
  std::printf("  seed 20261122\n");
  // Overwrite 64 bytes at 20 random places (past the 100-byte header): reads either succeed
  // with the right bytes or throw DatabaseError naming the file.
  for (int trial = 0; trial < 20; ++trial) {
    const fs::path p = dir / ("pages_" + std::to_string(trial) + ".db");
    fs::copy_file(good, p);
    {
      std::fstream f(p, std::ios::binary | std::ios::in | std::ios::out);
      const auto at = std::streamoff(100 + rng() % (size - 164));
      f.seekp(at);
      const Bytes junk = pattern(rng(), 64);
      f.write(reinterpret_cast<const char*>(junk.data()), 64);
    }
    SCOPED_TRACE("trial " + std::to_string(trial));
    try {
      const auto db = BlockDatabase::open(p.string());
      (void)db.check_integrity();
      for (BlockKey k : db.blocks()) try {
          const Bytes b = db.read_block(k);
          if (k.col >= 0 && k.col < 4 && k.row >= 0 && k.row < 3) {
            EXPECT_EQ(b, pattern(key_seed(k), std::size_t(1024 * (1 + k.col * 3 + k.row))));
          }
        } catch (const DatabaseError& e) {
          EXPECT_EQ(std::string(e.what()).rfind(p.string() + ": ", 0), 0u) << e.what();
        }
    } catch (const DatabaseError& e) {
      EXPECT_EQ(std::string(e.what()).rfind(p.string() + ": ", 0), 0u) << e.what();
    }
  }
}

TEST(BlockDatabase, TransactionsCommitOrRollBack) {
  const fs::path dir = fresh_dir("transactions");
  const std::string path = (dir / "terrain.db").string();
  auto db = BlockDatabase::create(path, sample_info());
  {
    BlockDatabase::Transaction t(db);
    db.put_block({0, 0}, pattern(1, 10));
    db.set_meta("k", "v");
    EXPECT_TRUE(db.has_block({0, 0}));                          // the writer sees its own writes
    EXPECT_FALSE(BlockDatabase::open(path).has_block({0, 0}));  // others do not, yet
    t.commit();
  }
  EXPECT_TRUE(BlockDatabase::open(path).has_block({0, 0}));
  {
    BlockDatabase::Transaction t(db);
    db.put_block({1, 0}, pattern(2, 10));
    db.put_block({0, 0}, pattern(3, 10));
    db.set_meta("k", "w");
  }  // not committed: rolled back
  EXPECT_FALSE(db.has_block({1, 0}));
  EXPECT_EQ(db.read_block({0, 0}), pattern(1, 10));
  EXPECT_EQ(db.get_meta("k"), "v");
  try {
    BlockDatabase::Transaction t(db);
    db.put_block({2, 0}, pattern(4, 10));
    throw std::runtime_error("build step failed");
  } catch (const std::runtime_error&) {
  }
  EXPECT_FALSE(db.has_block({2, 0}));
  // A new transaction works after a rollback; puts outside transactions commit one by one.
  {
    BlockDatabase::Transaction t(db);
    db.put_block({2, 0}, pattern(4, 10));
    t.commit();
  }
  db.put_block({3, 0}, pattern(5, 10));
  EXPECT_EQ(BlockDatabase::open(path).blocks(), (std::vector<BlockKey>{{0, 0}, {2, 0}, {3, 0}}));
}

// A blob written in pieces (put_blob_in_pieces) reads back as the same bytes as one put_blob,
// replaces an earlier blob of the name, and a wrong size or CRC fails and, inside a
// transaction, leaves the earlier blob; remove_blob removes one blob and ignores a missing one.
TEST(BlockDatabase, BlobsInPiecesAndRemoval) {
  const fs::path dir = fresh_dir("pieces");
  auto db = BlockDatabase::create((dir / "terrain.db").string(), sample_info());
  const Bytes whole = pattern(11, 3 * (1 << 20) + 12345);  // more than one 1 MiB write
  const std::uint32_t crc = terralod::pm::crc32_of(whole);
  auto fill_in = [&](std::size_t piece) {
    return [&whole, piece](const BlockDatabase::BlobPieceWriter& write) {
      for (std::size_t at = 0; at < whole.size(); at += piece)
        write(std::span<const std::uint8_t>(whole).subspan(at, std::min(piece, whole.size() - at)));
    };
  };
  db.put_blob("big", pattern(12, 10));
  for (std::size_t piece : {std::size_t(1), std::size_t(1000), std::size_t(1) << 20, whole.size()}) {
    if (piece == 1) {  // a byte at a time: 3 MB of calls would be slow; use the first 5000 bytes
      const Bytes head(whole.begin(), whole.begin() + 5000);
      db.put_blob_in_pieces("head", head.size(), terralod::pm::crc32_of(head),
                            [&](const BlockDatabase::BlobPieceWriter& write) {
                              for (std::uint8_t b : head) write(std::span<const std::uint8_t>(&b, 1));
                            });
      EXPECT_EQ(db.read_blob("head"), head);
      continue;
    }
    db.put_blob_in_pieces("big", whole.size(), crc, fill_in(piece));
    EXPECT_EQ(db.read_blob("big"), whole) << "pieces of " << piece;
  }
  db.put_blob_in_pieces("empty", 0, 0, [](const BlockDatabase::BlobPieceWriter&) {});
  EXPECT_EQ(db.read_blob("empty"), Bytes{});
  EXPECT_EQ(tb::BlockDatabase::open(db.path()).read_blob("big"), whole);  // committed, CRC checked
  auto expect_failure = [&](std::uint64_t size, std::uint32_t c, const std::string& says) {
    try {
      BlockDatabase::Transaction t(db);
      db.put_blob_in_pieces("big", size, c, fill_in(1 << 20));
      ADD_FAILURE() << "no error for size " << size;
    } catch (const tb::DatabaseError& e) {
      EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("terrain.db"), std::string::npos) << e.what();
    }
    EXPECT_EQ(db.read_blob("big"), whole);  // rolled back
  };
  expect_failure(whole.size() + 1, crc, "announced");
  expect_failure(whole.size() - 1, crc, "announced");
  expect_failure(whole.size(), crc ^ 1u, "CRC-32");
  db.remove_blob("big");
  db.remove_blob("never there");
  EXPECT_EQ(db.read_blob("big"), std::nullopt);
  EXPECT_EQ(db.blob_names(), (std::vector<std::string>{"empty", "head"}));
}

// Two reader threads read every block again and again while one writer adds blocks. Each
// reader has its own connection; every blob read must be exactly what was written (a block's
// bytes are a function of its key), and the readers must see the database grow.
TEST(BlockDatabase, ConcurrentReadersWhileWriting) {
  const fs::path dir = fresh_dir("concurrent");
  const std::string path = (dir / "terrain.db").string();
  auto writer = BlockDatabase::create(path, sample_info());
  const auto blob_for = [](BlockKey k) {
    return pattern(key_seed(k), 2000 + std::size_t(k.col * 131 + k.row * 17) % 30000);
  };
  for (int r = 0; r < 4; ++r) writer.put_block({0, r}, blob_for({0, r}));
  std::atomic<bool> done{false};
  std::atomic<int> failures{0};
  std::vector<std::size_t> reads(2, 0), max_seen(2, 0);
  const auto reader = [&](int id) {
    try {
      const auto db = BlockDatabase::open(path);
      while (true) {
        const bool last = done.load();  // one full pass after the writer finished
        const std::vector<BlockKey> keys = db.blocks();
        max_seen[std::size_t(id)] = std::max(max_seen[std::size_t(id)], keys.size());
        for (BlockKey k : keys) {
          if (db.read_block(k) != blob_for(k)) ++failures;
          ++reads[std::size_t(id)];
        }
        if (last) break;
      }
    } catch (const std::exception& e) {
      std::fprintf(stderr, "reader %d: %s\n", id, e.what());
      ++failures;
    }
  };
  std::thread a(reader, 0), b(reader, 1);
  for (int c = 1; c <= 12; ++c) {
    BlockDatabase::Transaction t(writer);  // a build commits a few blocks at a time
    for (int r = 0; r < 4; ++r) writer.put_block({c, r}, blob_for({c, r}));
    t.commit();
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  done = true;
  a.join();
  b.join();
  EXPECT_EQ(failures.load(), 0);
  for (int id = 0; id < 2; ++id) {
    EXPECT_EQ(max_seen[std::size_t(id)], 52u) << "reader " << id << " saw the final database";
    EXPECT_GE(reads[std::size_t(id)], 52u);
  }
  EXPECT_TRUE(writer.check_integrity().ok);
}

// ------------------------------------------------------------------------------------------
// Crash consistency: a child process writes blocks in a loop and is SIGKILLed at a random
// moment; the parent reopens the file and checks it; a second child resumes and is killed too;
// finally the parent resumes to completion.

constexpr int kCrashKeys = 16;

/// The child's blob for a key: 3 KB to ~1 MB, a deterministic function of the key.
Bytes crash_blob(std::uint64_t seed, BlockKey k) {
  const std::uint64_t s = seed ^ (key_seed(k) * 0xD6E8FEB86659FD93ull);
  return pattern(s, 3000 + std::size_t(std::mt19937_64(s)() % 1000000));
}

BlockKey crash_key(int i) { return {i % 4, i / 4}; }

/// Writes every missing key (the child's loop and the parent's resume).
void write_missing(const std::string& path, std::uint64_t seed) {
  auto db = fs::exists(path) ? BlockDatabase::open(path, BlockDatabase::Mode::ReadWrite)
                             : BlockDatabase::create(path, sample_info());
  for (int i = 0; i < kCrashKeys; ++i) {
    const BlockKey k = crash_key(i);
    if (db.has_block(k)) continue;
    if (i % 3 == 2) {  // some in a transaction with a meta update, like a build's batch
      BlockDatabase::Transaction t(db);
      db.put_block(k, crash_blob(seed, k));
      db.set_meta("last", std::to_string(i));
      t.commit();
    } else {
      db.put_block(k, crash_blob(seed, k));
    }
  }
  db.set_meta("build_complete", "1");
}

struct KillOutcome {
  bool killed = false;  ///< the child was still running when SIGKILL came
  bool interrupted_create = false;
  std::size_t blocks = 0;  ///< blocks present after the kill
  double child_us = 0;     ///< how long the child ran
};

/// Forks a child running write_missing(path), kills it after `delay_us`, then checks the file:
/// it opens, passes check_integrity, and every present block holds the child's bytes.
KillOutcome kill_and_check(const std::string& path, std::uint64_t seed, std::int64_t delay_us) {
  KillOutcome out;
  std::fflush(nullptr);
  const pid_t child = ::fork();
  if (child < 0) {
    ADD_FAILURE() << "fork failed";
    return out;
  }
  if (child == 0) {
    try {
      write_missing(path, seed);
    } catch (...) {
      ::_exit(3);
    }
    ::_exit(0);
  }
  // Wait until the deadline or the child's own end, whichever comes first.
  int status = 0;
  pid_t waited = 0;
  const auto start = std::chrono::steady_clock::now();
  const auto deadline = start + std::chrono::microseconds(delay_us);
  while ((waited = ::waitpid(child, &status, WNOHANG)) == 0 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(
        std::min(std::chrono::microseconds(500), std::chrono::microseconds(delay_us)));
  if (waited == 0) {
    ::kill(child, SIGKILL);
    waited = ::waitpid(child, &status, 0);
  }
  EXPECT_EQ(waited, child);
  out.child_us = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start).count();
  out.killed = WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL;
  if (!out.killed) {
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "the child failed";
  }
  if (!fs::exists(path)) return out;  // killed before create() made the file
  try {
    const auto db = BlockDatabase::open(path);
    const auto report = db.check_integrity();
    EXPECT_TRUE(report.ok) << (report.problems.empty() ? "" : report.problems.front());
    const std::vector<BlockKey> present = db.blocks();
    out.blocks = present.size();
    for (BlockKey k : present) EXPECT_EQ(db.read_block(k), crash_blob(seed, k)) << k.col << "," << k.row;
    EXPECT_EQ(db.info(), sample_info());
  } catch (const DatabaseError& e) {
    // The only acceptable failure: create() was killed before its single commit.
    EXPECT_EQ(std::string(e.what()), path + ": not a terralod database (interrupted create?)");
    out.interrupted_create = true;
    fs::remove(path);
  }
  return out;
}

// create() killed at random moments: the path holds nothing, an empty file open() calls an
// interrupted create, or a complete empty database; after removing the file, create() works
// again (stale -wal/-shm/-journal files beside it are discarded, never replayed).
TEST(BlockDatabase, SigkillDuringCreateLeavesNothingOrACompleteDatabase) {
  const std::uint64_t seed = 7;
  std::printf("  seed %llu\n", static_cast<unsigned long long>(seed));
  std::mt19937_64 rng(seed);
  const fs::path dir = fresh_dir("sigkill_create");
  const std::string path = (dir / "terrain.db").string();
  const auto create_in_child = [&](std::int64_t delay_us) {
    std::fflush(nullptr);
    const pid_t child = ::fork();
    if (child == 0) {
      try {
        (void)BlockDatabase::create(path, sample_info());
      } catch (...) {
        ::_exit(3);
      }
      ::_exit(0);
    }
    int status = 0;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::microseconds(delay_us);
    pid_t waited = 0;
    while ((waited = ::waitpid(child, &status, WNOHANG)) == 0 && std::chrono::steady_clock::now() < deadline)
      std::this_thread::yield();
    if (waited == 0) {
      ::kill(child, SIGKILL);
      waited = ::waitpid(child, &status, 0);
    }
    EXPECT_EQ(waited, child);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  };
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_EQ(create_in_child(10'000'000), 0);
  const double create_us =
      std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count();
  int nothing = 0, interrupted = 0, complete = 0;
  for (int trial = 0; trial < 100; ++trial) {
    SCOPED_TRACE("trial " + std::to_string(trial));
    fs::remove(path);  // leaves any -wal/-shm/-journal of the previous trial behind, as a user would
    const int exit =
        create_in_child(std::int64_t(std::uniform_real_distribution<double>(0.0, 1.2)(rng) * create_us));
    EXPECT_NE(exit, 3) << "create() failed in the child";
    if (!fs::exists(path)) {
      ++nothing;
      continue;
    }
    try {
      const auto db = BlockDatabase::open(path);
      EXPECT_EQ(db.info(), sample_info());
      EXPECT_TRUE(db.check_integrity().ok);
      EXPECT_TRUE(db.blocks().empty());
      ++complete;
    } catch (const DatabaseError& e) {
      EXPECT_EQ(std::string(e.what()), path + ": not a terralod database (interrupted create?)");
      EXPECT_TRUE(BlockDatabase::is_interrupted_create(path));
      ++interrupted;
    }
  }
  std::printf(
      "  100 kills during create(): %d left no file, %d an interrupted create, %d a complete database\n",
      nothing, interrupted, complete);
  EXPECT_GE(interrupted, 1);
  fs::remove(path);
  auto db = BlockDatabase::create(path, sample_info());
  db.put_block({0, 0}, pattern(1, 100));
  EXPECT_EQ(BlockDatabase::open(path).blocks().size(), 1u);
}

TEST(BlockDatabase, SigkillAtRandomMomentsLeavesAConsistentResumableDatabase) {
  const std::uint64_t seed = 20261122;
  std::printf("  seed %llu\n", static_cast<unsigned long long>(seed));
  const fs::path dir = fresh_dir("sigkill");
  std::mt19937_64 rng(seed);
  // Calibrate: how long does an uninterrupted run of the child take here?
  const KillOutcome full = kill_and_check((dir / "calibrate.db").string(), seed, 60'000'000);
  const double full_us = full.child_us;
  ASSERT_FALSE(full.killed);
  ASSERT_EQ(full.blocks, std::size_t(kCrashKeys));
  std::printf("  an uninterrupted run takes %.0f ms\n", full_us / 1000.0);

  // Trials until 12 runs were killed while writing (at most 30: a run that finished before its
  // kill time does not count).
  int trials = 0, kills = 0, interrupted_creates = 0;
  std::size_t partial = 0;
  for (; kills < 12 && trials < 30; ++trials) {
    SCOPED_TRACE("trial " + std::to_string(trials));
    const std::string path = (dir / ("trial_" + std::to_string(trials) + ".db")).string();
    // First kill anywhere in a run (trials 0 and 1: during create()), then kill the resumed run.
    const double f1 = trials < 2 ? 0.0005 * trials : std::uniform_real_distribution<double>(0.0, 0.8)(rng);
    const KillOutcome a = kill_and_check(path, seed, std::int64_t(f1 * full_us));
    const double f2 = std::uniform_real_distribution<double>(0.0, 0.5)(rng);
    const KillOutcome b = kill_and_check(path, seed, std::int64_t(f2 * full_us));
    if (b.killed && !b.interrupted_create) {
      EXPECT_GE(b.blocks, a.blocks);  // committed blocks never disappear
    }
    kills += a.killed;
    interrupted_creates += a.interrupted_create + b.interrupted_create;
    partial += (a.blocks > 0 && a.blocks < std::size_t(kCrashKeys)) +
               (b.blocks > 0 && b.blocks < std::size_t(kCrashKeys));
    // Resume to completion (kill_and_check already compared every block present after a kill).
    write_missing(path, seed);
    const auto db = BlockDatabase::open(path);
    EXPECT_TRUE(db.check_integrity().ok);
    ASSERT_EQ(db.blocks().size(), std::size_t(kCrashKeys));
    EXPECT_EQ(db.get_meta("build_complete"), "1");
    if (kills == 12) {
      for (BlockKey k : db.blocks()) EXPECT_EQ(db.read_block(k), crash_blob(seed, k));
    }
  }
  std::printf(
      "  %d trials: %d first runs killed while writing, %zu kills left a partial database, %d interrupted "
      "creates\n",
      trials, kills, partial, interrupted_creates);
  EXPECT_GE(kills, 10);
  EXPECT_GE(partial, 5u);  // the kills did land in the middle of the writing
}

}  // namespace
