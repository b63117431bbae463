// Bad input through every tool (issue 9, part 2): each command that reads a block database or a
// camera path (PATH.csv), run as the real binary on real files broken here, exits with status 1
// and one error line naming the file and the problem, and leaves nothing half-written: an output
// file is complete or absent, an output folder holds no partial file, no temporary beside the
// database, no half-stored texture layer.
//
// Databases: a 33 x 33 terrain built by 'terralod build' into 2 x 2 blocks of 17 samples, with a
// shading layer 'hill' ('terralod texture shade'), and a hybrid database ('terralod hybrid').
// Each broken copy is made with SQLite's C API:
//   missing        no file at all
//   not_sqlite     a text file
//   foreign        an SQLite file with another schema (one table t)
//   newer          format version 2 (PRAGMA user_version and the info row)
//   corrupt_block  one byte of block (1,1) flipped (its stored CRC-32 no longer matches)
//   cut_block      block (1,1) cut to half, with a matching size and CRC-32 (the PM decoder sees it)
//   short_blob     block (1,1) cut to half, size column unchanged (the database sees it)
//   interrupted    the 'build_complete' mark removed (a build killed before its end)
//   cut_tree       the approximation tree cut to half, with a matching size and CRC-32
//   corrupt_tile   one byte of the 'hill' tile (node -1, level 0) flipped
//   corrupt_hybrid one byte of the hybrid database's tree blob flipped
// Camera paths: junk lines, no header, a row of 5 columns, NaN and infinite values, an empty
// file, a header without rows, a missing file.
#include <gtest/gtest.h>
#include <sqlite3.h>
#include <zlib.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include "run_command.hpp"
#include "terralod/pm/mesh_io.hpp"

namespace {

namespace fs = std::filesystem;
namespace pm = terralod::pm;
namespace tt = terralod::test;
using tt::quote;

// ---------------------------------------------------------------------------------------------
// Inputs

// 33 x 33 samples, cellsize 30, lower-left corner (0, 0): x = 15 + 30 col, y = 15 + 30 (32 - row).
constexpr int kN = 33;
double height(double c, double r) {
  return 300.0 + 2.0 * c + r + 40.0 * std::sin(c / 4.0) * std::cos(r / 5.0);
}

const fs::path& dir() { return tt::process_temp_dir("bad-input-tools"); }

tt::CommandResult terralod(const std::string& args) {
  return tt::run_tool(TERRALOD_CLI, args, {.no_display = true});
}

struct Inputs {
  fs::path dem, db, hybrid, image, path, fast_path;
  std::string error;  // why the fixture could not be made, if it could not
};

/// Runs a SQL script on a copy's file (asserting success).
void exec_sql(const fs::path& file, const std::string& sql) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(file.c_str(), &db), SQLITE_OK) << file;
  char* msg = nullptr;
  const int rc = sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &msg);
  EXPECT_EQ(rc, SQLITE_OK) << file << ": " << (msg ? msg : "") << "\n" << sql;
  sqlite3_free(msg);
  ASSERT_EQ(sqlite3_close(db), SQLITE_OK) << file;
}

/// Replaces one blob cell: `select` returns the blob (one row), `update` takes ?1 = the new blob,
/// ?2 = its size, ?3 = its CRC-32; `edit` changes the bytes.
void edit_blob(const fs::path& file, const std::string& select, const std::string& update,
               const std::function<void(std::vector<unsigned char>&)>& edit) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(file.c_str(), &db), SQLITE_OK) << file;
  sqlite3_stmt* st = nullptr;
  ASSERT_EQ(sqlite3_prepare_v2(db, select.c_str(), -1, &st, nullptr), SQLITE_OK) << sqlite3_errmsg(db);
  ASSERT_EQ(sqlite3_step(st), SQLITE_ROW) << select;
  const auto* p = static_cast<const unsigned char*>(sqlite3_column_blob(st, 0));
  std::vector<unsigned char> bytes(p, p + sqlite3_column_bytes(st, 0));
  sqlite3_finalize(st);
  ASSERT_GT(bytes.size(), 16u);
  edit(bytes);
  ASSERT_EQ(sqlite3_prepare_v2(db, update.c_str(), -1, &st, nullptr), SQLITE_OK) << sqlite3_errmsg(db);
  sqlite3_bind_blob(st, 1, bytes.data(), int(bytes.size()), SQLITE_TRANSIENT);
  sqlite3_bind_int64(st, 2, sqlite3_int64(bytes.size()));
  sqlite3_bind_int64(st, 3, sqlite3_int64(crc32(0, bytes.data(), uInt(bytes.size()))));
  EXPECT_EQ(sqlite3_step(st), SQLITE_DONE) << update;
  EXPECT_EQ(sqlite3_changes(db), 1) << update;
  sqlite3_finalize(st);
  ASSERT_EQ(sqlite3_close(db), SQLITE_OK) << file;
}

void flip_middle(std::vector<unsigned char>& b) { b[b.size() / 2] ^= 0x40; }
void cut_half(std::vector<unsigned char>& b) { b.resize(b.size() / 2); }

void write_text(const fs::path& p, const std::string& text) {
  std::ofstream f(p, std::ios::binary | std::ios::trunc);
  f << text;
}

/// A camera path of `frames` frames 900 m over the terrain's centre, looking down at all of it.
std::string path_csv(int frames) {
  std::string s = "x,y,z,yaw,pitch,fovy\n";
  for (int f = 0; f < frames; ++f) s += std::to_string(480 + f) + ",480,900,0,-89,60\n";
  return s;
}

const Inputs& inputs() {
  static const Inputs in = [] {
    Inputs x;
    x.dem = dir() / "dem.asc";
    {
      std::ofstream f(x.dem);
      f << "ncols " << kN << "\nnrows " << kN
        << "\nxllcorner 0\nyllcorner 0\ncellsize 30\nNODATA_value -9999\n";
      for (int r = 0; r < kN; ++r)
        for (int c = 0; c < kN; ++c) f << std::round(height(c, r)) << (c + 1 < kN ? " " : "\n");
    }
    // 60 frames paced in real time (1 s: the loader reads all 4 blocks long before the end),
    // and 3 frames for the commands that only open the database.
    x.path = dir() / "path.csv";
    write_text(x.path, path_csv(60));
    x.fast_path = dir() / "fast.csv";
    write_text(x.fast_path, path_csv(3));
    x.db = dir() / "good.db";
    const std::string db = quote(x.db.string()), dem = quote(x.dem.string());
    for (const std::string& cmd :
         {"build --threads 1 --block-size 17 --input " + dem + " --out " + db,
          "texture shade " + db + " --layer hill --max-texture-size 16",
          "texture export " + db + " --layer hill --out " + quote((dir() / "image.png").string())}) {
      const tt::CommandResult r = terralod(cmd);
      if (r.status != 0) {
        x.error = "terralod " + cmd + ": " + r.err;
        return x;
      }
    }
    x.image = dir() / "image.png";
    // The hybrid database: a TIN of 4 x 4 squares of 2 samples from sample (8, 8), world frame.
    pm::TriangleMeshData tin;
    for (int j = 0; j <= 4; ++j)
      for (int i = 0; i <= 4; ++i) {
        const double c = 8 + 2 * i, r = 8 + 2 * j;
        tin.positions.push_back({15 + 30 * c, 15 + 30 * (32 - r), height(c, r)});
      }
    for (std::uint32_t j = 0; j < 4; ++j)
      for (std::uint32_t i = 0; i < 4; ++i) {
        const std::uint32_t a = j * 5 + i;
        tin.triangles.push_back({a, a + 6, a + 1});  // counter-clockwise seen from above
        tin.triangles.push_back({a, a + 5, a + 6});
      }
    pm::write_mesh(tin, (dir() / "tin.ply").string());
    x.hybrid = dir() / "hybrid.db";
    const tt::CommandResult h =
        terralod("hybrid --grid " + dem + " --grid-step 4 --levels 2 --tin " +
                 quote((dir() / "tin.ply").string()) + " --out " + quote(x.hybrid.string()));
    if (h.status != 0) x.error = "terralod hybrid: " + h.err;
    return x;
  }();
  return in;
}

// ---------------------------------------------------------------------------------------------
// Broken copies

struct Variant {
  std::string name;
  std::vector<std::vector<std::string>> problem;  // all groups must match; within one, any
};

/// A broken copy of good.db (or of hybrid.db for corrupt_hybrid) named after the variant, in a
/// folder of its own.
fs::path make_variant(const std::string& name, const fs::path& where) {
  const Inputs& in = inputs();
  fs::create_directories(where);
  const fs::path p = where / (name + ".db");
  fs::remove(p);
  if (name == "missing") return p;
  if (name == "not_sqlite") {
    std::string text;
    for (int i = 0; i < 200; ++i) text += "this is not a database\n";
    write_text(p, text);
    return p;
  }
  if (name == "foreign") {
    exec_sql(p, "CREATE TABLE t(a); INSERT INTO t VALUES (1);");
    return p;
  }
  fs::copy_file(name == "corrupt_hybrid" ? in.hybrid : in.db, p);
  const std::string block = "SELECT data FROM blocks WHERE col = 1 AND row = 1";
  if (name == "newer") {
    exec_sql(p, "PRAGMA user_version = 2; UPDATE info SET format_version = 2;");
  } else if (name == "corrupt_block") {
    edit_blob(p, block, "UPDATE blocks SET data = ?1 WHERE col = 1 AND row = 1", flip_middle);
  } else if (name == "cut_block") {
    edit_blob(p, block, "UPDATE blocks SET data = ?1, size = ?2, crc32 = ?3 WHERE col = 1 AND row = 1",
              cut_half);
  } else if (name == "short_blob") {
    edit_blob(p, block, "UPDATE blocks SET data = ?1 WHERE col = 1 AND row = 1", cut_half);
  } else if (name == "interrupted") {
    exec_sql(p, "DELETE FROM meta WHERE key = 'build_complete';");
  } else if (name == "cut_tree") {
    edit_blob(p, "SELECT data FROM blobs WHERE name = 'tree'",
              "UPDATE blobs SET data = ?1, size = ?2, crc32 = ?3 WHERE name = 'tree'", cut_half);
  } else if (name == "corrupt_tile") {
    edit_blob(p, "SELECT data FROM texture_tiles WHERE layer = 'hill' AND node = -1 AND level = 0",
              "UPDATE texture_tiles SET data = ?1 WHERE layer = 'hill' AND node = -1 AND level = 0",
              flip_middle);
  } else if (name == "corrupt_hybrid") {
    edit_blob(p, "SELECT data FROM blobs WHERE name = 'hybrid'",
              "UPDATE blobs SET data = ?1 WHERE name = 'hybrid'", flip_middle);
  } else {
    ADD_FAILURE() << "unknown variant " << name;
  }
  return p;
}

/// The problem each variant must be named by (every group must match one of its strings).
std::vector<std::vector<std::string>> problem_of(const std::string& name) {
  if (name == "missing") return {{"no such file"}};
  // Read-only opens say "not a SQLite database"; read-write ones SQLite's "file is not a database".
  if (name == "not_sqlite") return {{"not a SQLite database", "file is not a database"}};
  if (name == "foreign") return {{"not a terralod database"}};
  if (name == "newer") return {{"format version 2 is newer"}};
  if (name == "corrupt_block") return {{"block (1,1)"}, {"checksum mismatch"}};
  if (name == "cut_block" || name == "short_blob") return {{"block (1,1)"}, {"truncated"}};
  if (name == "interrupted") return {{"build is not complete"}};
  if (name == "cut_tree") return {{"tree"}};
  if (name == "corrupt_tile") return {{"texture tile", "layer 'hill'"}, {"checksum mismatch"}};
  if (name == "corrupt_hybrid") return {{"hybrid"}, {"checksum mismatch"}};
  return {};
}

/// Exit status 1 and exactly one error line "<tool>: ..." — the last line on stderr (progress
/// lines of earlier stages may precede it) — naming `file` and the problem.
void expect_error(const tt::CommandResult& r, const std::string& tool, const std::string& file,
                  const std::vector<std::vector<std::string>>& problem) {
  EXPECT_EQ(r.status, 1) << r.err << r.out;
  std::vector<std::string> errors;
  std::string last;
  for (const std::string& l : tt::lines_of(r.err)) {
    // A progress bar that was cut short leaves "stage: N%" without a newline before the error.
    const std::size_t at = l.find(tool + ": ");
    if (at != std::string::npos) errors.push_back(l.substr(at));
    if (!l.empty()) last = l;
  }
  ASSERT_EQ(errors.size(), 1u) << r.err;
  EXPECT_NE(last.find(errors[0]), std::string::npos) << "not the last line: " << r.err;
  EXPECT_NE(errors[0].find(file), std::string::npos) << "does not name " << file << ": " << errors[0];
  for (const auto& group : problem) {
    bool any = false;
    for (const std::string& s : group) any = any || errors[0].find(s) != std::string::npos;
    EXPECT_TRUE(any) << "lacks '" << group.front() << "': " << errors[0];
  }
}

/// No file under `folder` (recursively) but complete frame meshes of a flight that failed
/// half-way (frame_NNNNN.ply, each read back whole), and none beside `db` but the database's
/// own files.
void expect_nothing_half_written(const fs::path& folder, const fs::path& db) {
  if (fs::exists(folder))
    for (const auto& e : fs::recursive_directory_iterator(folder)) {
      const std::string n = e.path().filename().string();
      if (n.size() == 15 && n.rfind("frame_", 0) == 0 && e.path().extension() == ".ply") {
        EXPECT_NO_THROW(pm::read_ply(e.path().string())) << "partial frame mesh " << e.path();
        continue;
      }
      ADD_FAILURE() << "left behind: " << e.path();
    }
  for (const auto& e : fs::directory_iterator(db.parent_path())) {
    const std::string n = e.path().filename().string(), base = db.filename().string();
    if (n != base && n != base + "-wal" && n != base + "-shm")
      ADD_FAILURE() << "left beside the database: " << e.path();
  }
}

/// The texture layers listed in a database's meta table (the file must be an SQLite file).
std::vector<std::string> layers(const fs::path& db) {
  std::vector<std::string> out;
  sqlite3* h = nullptr;
  if (sqlite3_open_v2(db.c_str(), &h, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK) {
    sqlite3_close(h);
    return out;
  }
  sqlite3_stmt* st = nullptr;
  if (sqlite3_prepare_v2(h, "SELECT key FROM meta WHERE key LIKE 'texture_layer:%' ORDER BY key", -1, &st,
                         nullptr) == SQLITE_OK)
    while (sqlite3_step(st) == SQLITE_ROW)
      out.emplace_back(reinterpret_cast<const char*>(sqlite3_column_text(st, 0)));
  sqlite3_finalize(st);
  sqlite3_close(h);
  return out;
}

// ---------------------------------------------------------------------------------------------
// The commands that read a block database

struct DbCommand {
  std::string label;
  std::string tool = "terralod";
  /// The command line for database `db`, writing only under `out` (an empty folder).
  std::function<std::string(const fs::path& db, const fs::path& out)> args;
  std::vector<std::string> variants;  // the broken copies it must refuse
};

const std::vector<std::string> kOpenVariants = {"missing", "not_sqlite", "foreign", "newer"};

std::vector<std::string> with_open(std::vector<std::string> v) {
  v.insert(v.begin(), kOpenVariants.begin(), kOpenVariants.end());
  return v;
}

std::vector<DbCommand> db_commands() {
  const Inputs& in = inputs();
  const std::string dem = quote(in.dem.string()), cam = " --camera 480,-300,700,0,-35,60 --size 64x48";
  return {
      {"info", "terralod", [](const fs::path& db, const fs::path&) { return "info " + quote(db.string()); },
       with_open({})},
      {"extract --db", "terralod",
       [](const fs::path& db, const fs::path& out) {
         return "extract --db " + quote(db.string()) + " --max-error 1 --out " +
                quote((out / "x.ply").string());
       },
       with_open({"corrupt_block", "cut_block", "short_blob", "interrupted"})},
      {"fly --db", "terralod",
       [&in](const fs::path& db, const fs::path& out) {
         return "fly --db " + quote(db.string()) + " --path " + quote(in.path.string()) +
                " --size 64x48 --out " + quote(out.string()) + " --dump-meshes";
       },
       with_open({"corrupt_block", "cut_block", "short_blob", "interrupted"})},
      {"texture export", "terralod",
       [](const fs::path& db, const fs::path& out) {
         return "texture export " + quote(db.string()) + " --layer hill --out " +
                quote((out / "t.png").string());
       },
       with_open({"corrupt_tile"})},
      {"texture shade", "terralod",
       [](const fs::path& db, const fs::path&) {
         return "texture shade " + quote(db.string()) + " --layer shade2 --max-texture-size 16";
       },
       with_open({"corrupt_block", "cut_block", "short_blob", "interrupted", "cut_tree"})},
      {"texture add", "terralod",
       [&in](const fs::path& db, const fs::path&) {
         return "texture add " + quote(db.string()) + " --layer image2 --image " + quote(in.image.string()) +
                " --max-texture-size 16";
       },
       with_open({"interrupted", "cut_tree"})},
      {"view --texture-db", "terralod",
       [dem, cam](const fs::path& db, const fs::path& out) {
         return "view --input " + dem + " --texture-db " + quote(db.string()) + " --layer hill" + cam +
                " --out " + quote((out / "v.png").string());
       },
       with_open({"corrupt_tile"})},
      {"view --db", "terralod",
       [cam](const fs::path& db, const fs::path& out) {
         return "view --db " + quote(db.string()) + cam + " --out " + quote((out / "h.png").string());
       },
       with_open({"corrupt_hybrid"})},
      // Resuming a build reads the existing database first (a missing one is simply created).
      {"build (resume)",
       "terralod",
       [dem](const fs::path& db, const fs::path&) {
         return "build --threads 1 --block-size 17 --input " + dem + " --out " + quote(db.string());
       },
       {"not_sqlite", "foreign", "newer", "corrupt_block"}},
  };
}

void run_db_command(const DbCommand& c, const std::string& tool_path) {
  const Inputs& in = inputs();
  ASSERT_TRUE(in.error.empty()) << in.error;
  for (const std::string& v : c.variants) {
    SCOPED_TRACE(c.label + " on " + v);
    std::printf("%s on %s\n", c.label.c_str(), v.c_str());
    const fs::path where = dir() / (c.label.substr(0, c.label.find(' ')) + "_" + v);
    const fs::path db = make_variant(v, where);
    const std::vector<std::string> before = layers(db);
    const fs::path out = dir() / ("out_" + c.label.substr(0, c.label.find(' ')) + "_" + v);
    fs::create_directories(out);
    const tt::CommandResult r =
        tt::run_command(quote(tool_path) + " " + c.args(db, out), {.no_display = true});
    expect_error(r, c.tool, db.string(), problem_of(v));
    expect_nothing_half_written(out, db);
    if (fs::exists(db)) {
      EXPECT_EQ(layers(db), before) << "a layer was stored or removed";
    }
  }
}

TEST(BadInputTools, InfoAndExtractRefuseBrokenDatabases) {
  for (const DbCommand& c : db_commands())
    if (c.label == "info" || c.label == "extract --db") run_db_command(c, TERRALOD_CLI);
}

TEST(BadInputTools, FlyRefusesBrokenDatabases) {
  for (const DbCommand& c : db_commands())
    if (c.label == "fly --db") run_db_command(c, TERRALOD_CLI);
}

TEST(BadInputTools, TextureCommandsRefuseBrokenDatabases) {
  for (const DbCommand& c : db_commands())
    if (c.label.rfind("texture ", 0) == 0) run_db_command(c, TERRALOD_CLI);
}

TEST(BadInputTools, ViewAndBuildRefuseBrokenDatabases) {
  for (const DbCommand& c : db_commands())
    if (c.label.rfind("view ", 0) == 0 || c.label.rfind("build", 0) == 0) run_db_command(c, TERRALOD_CLI);
}

#ifdef TERRALOD_FLY
TEST(BadInputTools, FlightDemoRefusesBrokenTextureDatabases) {
  const Inputs& in = inputs();
  const DbCommand c{"terralod-fly --texture-db", "terralod-fly",
                    [&in](const fs::path& db, const fs::path& out) {
                      return "--headless --input " + quote(in.dem.string()) + " --texture-db " +
                             quote(db.string()) + " --layer hill --path " + quote(in.fast_path.string()) +
                             " --size 64x48 --out " + quote(out.string());
                    },
                    with_open({"corrupt_tile"})};
  run_db_command(c, TERRALOD_FLY);
}
#endif

TEST(BadInputTools, InterruptedBuildIsDescribedAsIncompleteAndResumed) {
  const Inputs& in = inputs();
  ASSERT_TRUE(in.error.empty()) << in.error;
  const fs::path db = make_variant("interrupted", dir() / "resume");
  const tt::CommandResult i = terralod("info " + quote(db.string()));
  ASSERT_EQ(i.status, 0) << i.err;
  EXPECT_NE(i.out.find("\"complete\": false"), std::string::npos) << i.out;
  // Running the build again finishes it; then every reader accepts it.
  const tt::CommandResult b = terralod("build --threads 1 --block-size 17 --input " + quote(in.dem.string()) +
                                       " --out " + quote(db.string()));
  ASSERT_EQ(b.status, 0) << b.err;
  const tt::CommandResult again = terralod("info " + quote(db.string()));
  EXPECT_NE(again.out.find("\"complete\": true"), std::string::npos) << again.out;
  const tt::CommandResult e = terralod("extract --db " + quote(db.string()) + " --max-error 1 --out " +
                                       quote((dir() / "resumed.ply").string()));
  EXPECT_EQ(e.status, 0) << e.err;
  EXPECT_GT(pm::read_ply((dir() / "resumed.ply").string()).triangles.size(), 0u);
}

// ---------------------------------------------------------------------------------------------
// Camera paths

struct PathCase {
  std::string name, text;
  std::vector<std::string> problem;
};

const std::vector<PathCase> kPaths = {
    {"junk", "x,y,z,yaw,pitch,fovy\n480,480,900,0,-89,60\nthis is junk\n", {"line 3", "6 comma-separated"}},
    {"binary", "x,y,z,yaw,pitch,fovy\n480,480,900,0,-89,60\n\x01\xff\xfe,\x80\n", {"line 3"}},
    {"no_header", "480,480,900,0,-89,60\n", {"line 1", "header"}},
    {"columns", "x,y,z,yaw,pitch,fovy\n480,480,900,0,-89\n", {"line 2", "found 5 fields"}},
    {"extra_column", "x,y,z,yaw,pitch,fovy\n480,480,900,0,-89,60,7\n", {"line 2", "found 7 fields"}},
    {"nan", "x,y,z,yaw,pitch,fovy\n480,nan,900,0,-89,60\n", {"line 2", "not a finite number"}},
    {"inf", "x,y,z,yaw,pitch,fovy\n480,480,inf,0,-89,60\n", {"line 2", "not a finite number"}},
    {"huge", "x,y,z,yaw,pitch,fovy\n480,480,1e999,0,-89,60\n", {"line 2", "not a finite number"}},
    {"pitch", "x,y,z,yaw,pitch,fovy\n480,480,900,0,-91,60\n", {"line 2", "pitch"}},
    {"empty", "", {"empty"}},
    {"header_only", "x,y,z,yaw,pitch,fovy\n", {"no camera rows"}},
};

void run_path_cases(const std::string& tool, const std::string& tool_path,
                    const std::function<std::string(const fs::path& csv, const fs::path& out)>& args) {
  const Inputs& in = inputs();
  ASSERT_TRUE(in.error.empty()) << in.error;
  std::vector<PathCase> cases = kPaths;
  cases.push_back({"missing", "", {"no such file"}});
  for (const PathCase& p : cases) {
    SCOPED_TRACE(tool + " --path " + p.name);
    std::printf("%s --path %s\n", tool.c_str(), p.name.c_str());
    const fs::path folder = dir() / (tool + "_path_" + p.name);
    fs::create_directories(folder);
    const fs::path csv = folder / "path.csv", out = folder / "out";
    fs::create_directories(out);
    if (p.name != "missing") write_text(csv, p.text);
    const tt::CommandResult r =
        tt::run_command(quote(tool_path) + " " + args(csv, out), {.no_display = true});
    expect_error(r, tool, csv.string(), {p.problem});
    for (const std::string& s : p.problem) EXPECT_NE(r.err.find(s), std::string::npos) << s << ": " << r.err;
    EXPECT_FALSE(fs::exists(out / "frames.csv")) << out;
    if (fs::exists(out))
      for (const auto& e : fs::recursive_directory_iterator(out))
        ADD_FAILURE() << "left behind: " << e.path();
  }
}

TEST(BadInputTools, FlyRefusesBadCameraPaths) {
  const Inputs& in = inputs();
  run_path_cases("terralod", TERRALOD_CLI, [&in](const fs::path& csv, const fs::path& out) {
    return "fly --db " + quote(in.db.string()) + " --path " + quote(csv.string()) + " --size 64x48 --out " +
           quote(out.string());
  });
}

#ifdef TERRALOD_FLY
TEST(BadInputTools, FlightDemoRefusesBadCameraPaths) {
  const Inputs& in = inputs();
  run_path_cases("terralod-fly", TERRALOD_FLY, [&in](const fs::path& csv, const fs::path& out) {
    return "--headless --input " + quote(in.dem.string()) + " --path " + quote(csv.string()) +
           " --size 64x48 --out " + quote(out.string());
  });
}
#endif

}  // namespace
