// Tests for building and using a block database (tree_builder.hpp build_database,
// database_extract.hpp): summary, exact leaf errors, extraction within E and watertight on a
// generated terrain and on N44W072, resume after an interruption, SIGKILL of the real
// `terralod build` at random moments, and bad input through the command line.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <thread>

#include "hot_journal.hpp"
#include "mesh_checker.hpp"
#include "run_command.hpp"
#include "terralod/blocks/database_extract.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/mesh_io.hpp"
#include "terralod/pm/pm_io.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace {

namespace fs = std::filesystem;
namespace tb = terralod::blocks;
namespace pm = terralod::pm;

std::string tmp(const std::string& name) {
  const std::string p = std::string(TERRALOD_TEST_TMP) + "/database_build_" + name;
  for (const std::string& f : {p, p + "-wal", p + "-shm", p + "-journal"}) fs::remove(f);
  return p;
}

pm::Heightfield terrain(int w, int h, std::uint64_t seed) {
  pm::TerrainOptions o;
  o.width = w;
  o.height = h;
  o.seed = seed;
  o.quantize_to_metres = true;
  pm::Heightfield hf = pm::generate_terrain(o);
  hf.source = "generated";
  return hf;
}

/// Extraction at E is within E (independent exact check) and one watertight cover.
void check_extraction(const pm::Heightfield& hf, const std::string& db, double E) {
  SCOPED_TRACE("E = " + std::to_string(E));
  const tb::ExtractedMesh m = tb::extract_mesh(db, E);
  EXPECT_EQ(m.heightfield.samples(), hf.samples());
  EXPECT_EQ(m.heightfield.transform, hf.transform);
  EXPECT_LE(m.measured_error, E);
  EXPECT_EQ(m.mesh.error_bound, m.measured_error);
  const terralod::test::MeshCheck c = terralod::test::check_mesh(hf, m.mesh);
  EXPECT_TRUE(c.ok(E)) << c.describe();
  EXPECT_NEAR(c.max_continuous_error(), m.measured_error, 1e-9 + c.tolerance);
}

TEST(DatabaseBuild, GeneratedTerrainSummaryTreeAndExtraction) {
  const pm::Heightfield hf = terrain(129, 113, 4);
  const std::string path = tmp("generated.db");
  tb::DatabaseBuildOptions opt;
  opt.block_size = 33;
  opt.threads = 2;
  const tb::DatabaseSummary s = tb::build_database(hf, path, opt);
  EXPECT_TRUE(s.complete);
  EXPECT_EQ(s.blocks, 4u * 4u);  // 128 / 32 = 4 columns, 112 / 32 = 3.5 -> 4 rows
  EXPECT_EQ(s.blocks_built, s.blocks);
  EXPECT_EQ(s.nodes_per_strategy[std::size_t(tb::Strategy::PmBlock)], s.blocks);
  EXPECT_EQ(s.samples, 129u * 113u);
  EXPECT_GT(s.bytes_per_vertex, 0.0);

  const tb::BlockDatabase db = tb::BlockDatabase::open(path);
  EXPECT_TRUE(db.check_integrity().ok);
  const tb::DatabaseSummary again = tb::summarize_database(db);
  // Reading a database runs no build: "built by this run" is the build's alone (info printed 0).
  EXPECT_FALSE(again.blocks_built.has_value());
  EXPECT_EQ(again.to_json().find("blocks_built"), std::string::npos) << again.to_json();
  EXPECT_NE(s.to_json().find("\"blocks_built\": 16"), std::string::npos) << s.to_json();
  EXPECT_EQ(again.nodes, s.nodes);
  EXPECT_EQ(again.block_bytes, s.block_bytes);
  // The tree: leaves are the blocks, their error the exact error of the decoded block's base mesh.
  const tb::ApproximationTree tree = tb::decode_tree(*db.read_blob("tree"), "tree");
  EXPECT_EQ(tree.size(), s.nodes);
  const tb::BlockLayout l = tb::partition(129, 113, 33);
  for (const tb::TreeNode& n : tree.nodes()) {
    if (n.strategy != tb::Strategy::PmBlock) continue;
    const pm::ProgressiveMesh p = pm::decode_pm(db.read_block(*n.block), "block");
    EXPECT_EQ(n.domain, l.rect(*n.block));
    const pm::TriangleMesh base = p.extract_after(p.vsplit_count());
    double brute = 0.0;
    for (const auto& t : base.triangles)
      brute = std::max(brute, terralod::test::triangle_error(p.heightfield(), base.vertices[t[0]],
                                                             base.vertices[t[1]], base.vertices[t[2]])
                                  .max());
    EXPECT_EQ(n.error, brute);
  }
  for (double E : {0.0, 1.0, 4.0, 25.0, 400.0}) check_extraction(hf, path, E);
  // A second build with the same options finds everything done; other options are refused.
  EXPECT_EQ(tb::build_database(hf, path, opt).blocks_built, 0u);
  tb::DatabaseBuildOptions other = opt;
  other.block_size = 17;
  try {
    tb::build_database(hf, path, other);
    ADD_FAILURE() << "different parameters accepted";
  } catch (const tb::BuildError& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("other parameters"), std::string::npos) << e.what();
  }
  // The builder's revision is one of them: a database begun by another revision is not resumed.
  EXPECT_NE(tb::BlockDatabase::open(path).info().build_parameters.find(
                "\"pm_builder\": " + std::to_string(pm::ProgressiveMesh::kBuilderRevision)),
            std::string::npos);
}

// What a killed create() leaves (an empty file, or a hot journal over one: block_database.hpp)
// is replaced by a fresh build; a foreign file with a hot journal holds data: it is refused and
// kept.
TEST(DatabaseBuild, StartsOverOnAnInterruptedCreateOnly) {
  const pm::Heightfield hf = terrain(65, 65, 9);
  tb::DatabaseBuildOptions opt;
  opt.block_size = 33;
  opt.threads = 2;
  const std::string ref = tmp("interrupted_ref.db");
  tb::build_database(hf, ref, opt);
  const tb::BlockDatabase want = tb::BlockDatabase::open(ref);
  const std::string empty = tmp("interrupted_empty.db"), hot = tmp("interrupted_hot.db");
  std::ofstream(empty).close();
  terralod::test::leave_hot_journal(hot, "");
  for (const std::string& path : {empty, hot}) {
    SCOPED_TRACE(path);
    EXPECT_TRUE(tb::build_database(hf, path, opt).complete);
    const tb::BlockDatabase db = tb::BlockDatabase::open(path);
    EXPECT_TRUE(db.check_integrity().ok);
    EXPECT_EQ(db.blocks(), want.blocks());
    EXPECT_EQ(db.read_blob("tree"), want.read_blob("tree"));
    EXPECT_FALSE(fs::exists(path + "-journal"));
  }
  const std::string foreign = tmp("interrupted_foreign.db");
  terralod::test::leave_hot_journal(foreign, "CREATE TABLE places(name TEXT)");
  try {
    tb::build_database(hf, foreign, opt);
    ADD_FAILURE() << "a foreign file was built over";
  } catch (const tb::DatabaseError& e) {
    // The read-write open rolls the journal back (SQLite's own recovery): what is left is the
    // foreign file as last committed, refused and kept.
    EXPECT_EQ(std::string(e.what()), foreign + ": not a terralod database (an SQLite file of another kind)");
  }
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open_v2(foreign.c_str(), &db, SQLITE_OPEN_READONLY, nullptr), SQLITE_OK);
  sqlite3_stmt* st = nullptr;
  ASSERT_EQ(sqlite3_prepare_v2(db, "SELECT group_concat(name) FROM sqlite_schema", -1, &st, nullptr),
            SQLITE_OK);
  ASSERT_EQ(sqlite3_step(st), SQLITE_ROW);
  EXPECT_STREQ(reinterpret_cast<const char*>(sqlite3_column_text(st, 0)), "places");
  sqlite3_finalize(st);
  sqlite3_close(db);
}

TEST(DatabaseBuild, ResumeAfterAnInterruption) {
  const pm::Heightfield hf = terrain(97, 97, 8);
  tb::DatabaseBuildOptions opt;
  opt.block_size = 33;
  opt.threads = 2;
  opt.tree.levels = {tb::StrategyChoice::Grid, tb::StrategyChoice::Tin};
  const std::string fresh = tmp("fresh.db"), resumed = tmp("resumed.db");
  tb::build_database(hf, fresh, opt);
  tb::DatabaseBuildOptions stop = opt;
  stop.stop_after_blocks = 4;
  EXPECT_THROW(tb::build_database(hf, resumed, stop), tb::BuildError);
  {
    const tb::BlockDatabase db = tb::BlockDatabase::open(resumed);
    EXPECT_TRUE(db.check_integrity().ok);
    const tb::DatabaseSummary part = tb::summarize_database(db);
    EXPECT_FALSE(part.complete);
    EXPECT_GE(part.blocks, 4u);
    EXPECT_THROW(tb::extract_mesh(db, 1.0), tb::BuildError);
  }
  const tb::DatabaseSummary s = tb::build_database(hf, resumed, opt);
  EXPECT_TRUE(s.complete);
  EXPECT_EQ(s.blocks, 9u);
  EXPECT_LT(s.blocks_built, 9u);
  // Same content as an uninterrupted build.
  const tb::BlockDatabase a = tb::BlockDatabase::open(fresh), b = tb::BlockDatabase::open(resumed);
  EXPECT_EQ(a.blocks(), b.blocks());
  for (tb::BlockKey k : a.blocks()) EXPECT_EQ(a.read_block(k), b.read_block(k));
  EXPECT_EQ(a.read_blob("tree"), b.read_blob("tree"));
  const tb::ExtractedMesh ma = tb::extract_mesh(a, 3.0), mb = tb::extract_mesh(b, 3.0);
  EXPECT_EQ(ma.mesh.vertices, mb.mesh.vertices);
  EXPECT_EQ(ma.mesh.triangles, mb.mesh.triangles);
}

TEST(DatabaseBuild, N44W072Crop) {
  const std::string hgt = std::string(TERRALOD_DATA_DIR) + "/N44W072.hgt";
  if (!fs::exists(hgt)) GTEST_SKIP() << hgt << " is absent";
  const pm::Heightfield full = tb::read_dem(hgt);
  // A 257 x 225 crop around the steepest part of the tile (2 x 2 blocks of 129, the last row
  // partial): the whole tile takes ~15 s to build on 2 cores; the crop keeps the test fast.
  pm::Heightfield hf(257, 225);
  for (int r = 0; r < hf.height(); ++r)
    for (int c = 0; c < hf.width(); ++c) hf.at(c, r) = full.at(c + 400, r + 300);
  hf.transform = full.transform;
  hf.source = hgt + " (crop)";
  const std::string path = tmp("n44w072.db");
  tb::DatabaseBuildOptions opt;
  opt.block_size = 129;
  opt.threads = 2;
  const tb::DatabaseSummary s = tb::build_database(hf, path, opt);
  EXPECT_EQ(s.blocks, 4u);
  for (double E : {2.0, 10.0}) check_extraction(hf, path, E);
}

// ---------------------------------------------------------------------------------------------
// The real binary

void write_asc(const std::string& path, const pm::Heightfield& hf, bool all_void = false) {
  std::ofstream f(path);
  f << "ncols " << hf.width() << "\nnrows " << hf.height()
    << "\nxllcorner 0\nyllcorner 0\ncellsize 30\nNODATA_value -9999\n";
  for (int r = 0; r < hf.height(); ++r) {
    for (int c = 0; c < hf.width(); ++c) f << (all_void ? -9999.0 : hf.at(c, r)) << ' ';
    f << '\n';
  }
}

struct ChildRun {
  int status = -1;  ///< exit code, or -signal
  std::string err;
};

/// Runs `terralod args...`; kills it with SIGKILL after kill_after_ms when >= 0.
ChildRun run_terralod(const std::vector<std::string>& args, double kill_after_ms = -1.0) {
  // One file per test process: ctest runs the cases of this file in parallel processes.
  const std::string err_path =
      std::string(TERRALOD_TEST_TMP) + "/database_build_stderr_" + std::to_string(::getpid()) + ".txt";
  const pid_t pid = fork();
  if (pid == 0) {
    const int fd = ::open(err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(fd, 2);
    const int null = ::open("/dev/null", O_WRONLY);
    dup2(null, 1);
    std::vector<char*> argv{const_cast<char*>(TERRALOD_BINARY)};
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    execv(TERRALOD_BINARY, argv.data());
    _exit(127);
  }
  ChildRun r;
  if (kill_after_ms >= 0) {
    std::this_thread::sleep_for(std::chrono::duration<double, std::milli>(kill_after_ms));
    kill(pid, SIGKILL);
  }
  int st = 0;
  waitpid(pid, &st, 0);
  r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -WTERMSIG(st);
  std::ifstream f(err_path);
  r.err.assign(std::istreambuf_iterator<char>(f), {});
  return r;
}

TEST(DatabaseBuild, SigkillAtRandomMomentsThenResume) {
  const pm::Heightfield hf = terrain(97, 97, 5);
  const std::string asc = std::string(TERRALOD_TEST_TMP) + "/database_build_kill.asc";
  write_asc(asc, hf);
  const std::vector<std::string> base{"build",     "--input", asc,          "--block-size", "33",
                                      "--threads", "2",       "--strategy", "grid,tin"};
  // Time of a complete build, to spread the kills over it.
  const std::string ref = tmp("kill_ref.db");
  auto args = base;
  args.insert(args.end(), {"--out", ref});
  const auto t0 = std::chrono::steady_clock::now();
  const ChildRun full = run_terralod(args);
  const double full_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_EQ(full.status, 0) << full.err;
  const std::uint32_t seed = 4242;
  std::printf("seed %u, full build %.0f ms\n", seed, full_ms);
  std::mt19937 rng(seed);
  int killed = 0, interrupted_creates = 0;
  // The resume runs in this process (same options as the command line), which saves a process
  // start per trial; the command line's own resume is exercised by CliInfoAndExtract's rebuild.
  const pm::Heightfield input = tb::read_dem(asc);
  tb::DatabaseBuildOptions same;
  same.block_size = 33;
  same.threads = 2;
  same.tree.levels = {tb::StrategyChoice::Grid, tb::StrategyChoice::Tin};
  for (int trial = 0; trial < 10; ++trial) {
    const std::string path = tmp("kill.db");
    auto a = base;
    a.insert(a.end(), {"--out", path});
    const double at = std::uniform_real_distribution<double>(0.0, 0.9 * full_ms)(rng);
    const ChildRun r = run_terralod(a, at);
    SCOPED_TRACE("trial " + std::to_string(trial) + ", kill at " + std::to_string(at) + " ms");
    if (r.status == -SIGKILL) ++killed;
    if (fs::exists(path)) {
      try {
        const tb::BlockDatabase db = tb::BlockDatabase::open(path);
        const auto report = db.check_integrity();
        EXPECT_TRUE(report.ok) << (report.problems.empty() ? "" : report.problems[0]);
      } catch (const tb::DatabaseError& e) {
        // Only a create() killed before its commit may leave a file that does not open.
        EXPECT_NE(std::string(e.what()).find("interrupted create"), std::string::npos) << e.what();
        ++interrupted_creates;
      }
    }
    const tb::DatabaseSummary resumed = tb::build_database(input, path, same);
    EXPECT_TRUE(resumed.complete);
    const tb::BlockDatabase db = tb::BlockDatabase::open(path);
    EXPECT_TRUE(db.check_integrity().ok);
    const tb::BlockDatabase want = tb::BlockDatabase::open(ref);
    EXPECT_EQ(db.blocks(), want.blocks());
    EXPECT_EQ(db.read_blob("tree"), want.read_blob("tree"));
  }
  std::printf("%d of 10 builds killed before finishing, %d inside create()\n", killed, interrupted_creates);
}

// terralod info DB prints the summary; terralod extract --db writes the stitched mesh.
TEST(DatabaseBuild, CliInfoAndExtract) {
  const pm::Heightfield hf = terrain(65, 65, 6);
  const std::string asc = std::string(TERRALOD_TEST_TMP) + "/database_build_cli.asc";
  write_asc(asc, hf);
  const std::string db = tmp("cli.db"), ply = std::string(TERRALOD_TEST_TMP) + "/database_build_cli.ply";
  ASSERT_EQ(
      run_terralod({"build", "--input", asc, "--out", db, "--block-size", "33", "--strategy", "auto"}).status,
      0);
  // Running the same command again resumes (here: finds everything built) and succeeds.
  ASSERT_EQ(
      run_terralod({"build", "--input", asc, "--out", db, "--block-size", "33", "--strategy", "auto"}).status,
      0);
  EXPECT_EQ(run_terralod({"info", db}).status, 0);
  const ChildRun r =
      run_terralod({"extract", "--db", db, "--max-error", "3", "--out", ply, "--units", "samples"});
  ASSERT_EQ(r.status, 0) << r.err;
  const pm::TriangleMeshData mesh = pm::read_ply(ply);
  const tb::ExtractedMesh want = tb::extract_mesh(db, 3.0);
  ASSERT_EQ(mesh.positions.size(), want.mesh.vertices.size());
  EXPECT_EQ(mesh.triangles, want.mesh.triangles);
  for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
    const std::uint32_t s = want.mesh.vertices[v];
    EXPECT_EQ(mesh.positions[v][0], double(s % 65));
    EXPECT_EQ(mesh.positions[v][1], double(s / 65));
    EXPECT_EQ(mesh.positions[v][2], hf.at(int(s % 65), int(s / 65)));
  }
  // Both of --input and --db, or neither: a usage error.
  EXPECT_EQ(run_terralod({"extract", "--max-error", "3", "--out", ply}).status, 2);
}

TEST(DatabaseBuild, BadInputNamesTheFile) {
  const std::string dir = std::string(TERRALOD_TEST_TMP);
  const std::string out = tmp("bad.db");
  auto expect_error = [&](const std::string& input, const std::string& what) {
    const ChildRun r = run_terralod({"build", "--input", input, "--out", out});
    EXPECT_EQ(r.status, 1) << what << ": " << r.err;
    EXPECT_NE(r.err.find(input), std::string::npos) << what << ": " << r.err;
    EXPECT_FALSE(fs::exists(out)) << what << ": a database was left behind";
  };
  expect_error(dir + "/database_build_missing.hgt", "missing file");
  {
    std::ofstream(dir + "/database_build_garbage.hgt") << "this is not an elevation model";
    expect_error(dir + "/database_build_garbage.hgt", "unreadable format");
  }
  write_asc(dir + "/database_build_1x1.asc", pm::Heightfield(1, 1));
  expect_error(dir + "/database_build_1x1.asc", "1 x 1 grid");
  write_asc(dir + "/database_build_void.asc", terrain(9, 9, 1), /*all_void=*/true);
  expect_error(dir + "/database_build_void.asc", "all voids");
  {  // One valid sample, voids kept: no triangle, and the message does not say that all are void.
    pm::Heightfield lone = terrain(9, 9, 1);
    std::vector<std::uint8_t> mask(lone.size(), 0);
    mask[4 * 9 + 4] = 1;
    lone.set_mask(std::move(mask));
    const std::string input = dir + "/database_build_lone.asc";
    std::ofstream f(input);
    f << "ncols 9\nnrows 9\nxllcorner 0\nyllcorner 0\ncellsize 30\nNODATA_value -9999\n";
    for (std::size_t i = 0; i < lone.size(); ++i)
      f << (lone.valid(i) ? lone[i] : -9999.0) << (i % 9 == 8 ? '\n' : ' ');
    f.close();
    const ChildRun r = run_terralod({"build", "--keep-voids", "--input", input, "--out", out});
    EXPECT_EQ(r.status, 1) << r.err;
    EXPECT_NE(r.err.find(input + ": no triangle of valid samples"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(out));
  }
  // The library refuses them too, naming the source.
  pm::Heightfield one(1, 1);
  one.source = "one.asc";
  try {
    tb::build_database(one, out, {});
    ADD_FAILURE() << "1 x 1 accepted";
  } catch (const tb::BuildError& e) {
    EXPECT_NE(std::string(e.what()).find("one.asc"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(out));
  // An empty folder, and a mosaic with a missing tile, are refused naming them.
  fs::create_directories(dir + "/database_build_no_tiles");
  expect_error(dir + "/database_build_no_tiles", "a folder without elevation files");
  // A tile without a CRS beside one with a CRS does not mosaic (tiles in two CRSs do: one is
  // warped to the other's, see test_dem_writer): the error names both and says why, once
  // (GDAL's own warning used to be printed before it as well).
  const std::string zones = dir + "/database_build_zones";
  fs::create_directories(zones);
  write_asc(zones + "/plain.asc", terrain(9, 9, 1));
  write_asc(zones + "/utm18.asc", terrain(9, 9, 1));
  std::ofstream(zones + "/utm18.prj")
      << "PROJCS[\"WGS 84 / UTM zone 18N\",GEOGCS[\"WGS 84\",DATUM[\"WGS_1984\",SPHEROID[\"WGS 84\",6378137,"
         "298.257223563]],PRIMEM[\"Greenwich\",0],UNIT[\"degree\",0.0174532925199433]],PROJECTION["
         "\"Transverse_Mercator\"],PARAMETER[\"latitude_of_origin\",0],PARAMETER[\"central_meridian\",-75],"
         "PARAMETER[\"scale_factor\",0.9996],PARAMETER[\"false_easting\",500000],PARAMETER[\"false_"
         "northing\",0],"
         "UNIT[\"metre\",1]]";
  expect_error(zones, "a tile without a CRS");
  const ChildRun z = run_terralod({"build", "--input", zones, "--out", out});
  const std::size_t why = z.err.find("plain.asc: it has no CRS while " + zones + "/utm18.asc has one");
  EXPECT_NE(why, std::string::npos) << z.err;
  EXPECT_EQ(z.err.find("has no CRS", why + 20), std::string::npos) << "said twice: " << z.err;
}

// --input FOLDER and repeated --input: the tiles are built as one terrain, the database says so.
TEST(DatabaseBuild, CliBuildsAFolderOrAListOfTilesAsOneMosaic) {
  const std::string dir = std::string(TERRALOD_TEST_TMP) + "/database_build_tiles";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const pm::Heightfield hf = terrain(65, 65, 7);
  write_asc(dir + "/source.asc", hf);
  ASSERT_EQ(run_terralod({"testdem", "--mirror", dir + "/source.asc", "--tiles", "2x1", "--out", dir + "/m"})
                .status,
            0);
  ASSERT_EQ(run_terralod({"testdem", "--mirror", dir + "/source.asc", "--tiles", "3x1", "--out", dir + "/m3"})
                .status,
            0);
  const std::string folder = tmp("tiles_folder.db"), listed = tmp("tiles_listed.db");
  ChildRun r = run_terralod({"build", "--input", dir + "/m", "--out", folder, "--block-size", "33"});
  ASSERT_EQ(r.status, 0) << r.err;
  // A mosaic of GeoTIFFs without a CRS needs no warp: read window by window; the build ends with
  // its peak memory. An ASCII grid too, through the temporary file it is decoded to.
  namespace tt = terralod::test;
  const auto cli = [&](const std::string& input, const std::string& out) {
    return tt::run_command(tt::quote(TERRALOD_BINARY) + " build --block-size 33 --input " + tt::quote(input) +
                           " --out " + tt::quote(tmp(out)));
  };
  const auto windowed = cli(dir + "/m", "tiles_windowed.db");
  ASSERT_EQ(windowed.status, 0) << windowed.err;
  EXPECT_NE(windowed.out.find("read window by window"), std::string::npos) << windowed.out;
  EXPECT_NE(windowed.out.find("memory peak resident "), std::string::npos) << windowed.out;
  const auto whole = cli(dir + "/source.asc", "tiles_asc.db");
  ASSERT_EQ(whole.status, 0) << whole.err;
  EXPECT_NE(whole.out.find("read window by window"), std::string::npos) << whole.out;
  r = run_terralod({"build", "--input", dir + "/m/tile_0_0.tif", "--input", dir + "/m/tile_0_1.tif", "--out",
                    listed, "--block-size", "33"});
  ASSERT_EQ(r.status, 0) << r.err;
  for (const std::string& path : {folder, listed}) {
    const tb::BlockDatabase db = tb::BlockDatabase::open(path);
    EXPECT_EQ(db.info().grid_width, 129);  // 2 x 64 + 1: the tiles share their edge column
    EXPECT_EQ(db.info().grid_height, 65);
    EXPECT_NE(db.info().source.find("mosaic of 2 files: tile_0_0.tif, tile_0_1.tif"), std::string::npos)
        << db.info().source;
  }
  // The same samples (the build parameters carry their CRC-32); the blocks differ only by the
  // source text each PM records.
  EXPECT_EQ(tb::BlockDatabase::open(folder).info().build_parameters,
            tb::BlockDatabase::open(listed).info().build_parameters);
  // Two tiles with the middle one missing: the gap (63 x 65 samples) is filled once, by the first
  // block that meets it, and its values reused by the others (one thread: no two first blocks).
  const auto gap =
      tt::run_command(tt::quote(TERRALOD_BINARY) + " build --block-size 33 --threads 1 --input " +
                      tt::quote(dir + "/m3/tile_0_0.tif") + " --input " +
                      tt::quote(dir + "/m3/tile_0_2.tif") + " --out " + tt::quote(tmp("tiles_gap.db")));
  ASSERT_EQ(gap.status, 0) << gap.err;
  EXPECT_NE(gap.out.find("voids 1 regions solved (4095 samples), "), std::string::npos) << gap.out;
  EXPECT_EQ(gap.out.find(", 0 times a large filled region was reused"), std::string::npos) << gap.out;
  EXPECT_EQ(windowed.out.find("regions solved"), std::string::npos) << "no void, no line: " << windowed.out;
  EXPECT_EQ(run_terralod({"build", "--input", dir + "/m/tile_0_0.tif", "--input", dir + "/m/none.tif",
                          "--out", tmp("tiles_missing.db")})
                .status,
            1);
}

}  // namespace

// The heightmap and band options reach the build: a 16-bit PGM built with --vertical-scale and
// --spacing (build had neither: a game heightmap's raw units became metres on 1 m cells), and a
// raster of two bands (heights, then a constant uncertainty, as in a BAG), refused without --band
// and built from the band it names.
TEST(DatabaseBuild, CliTakesHeightmapScalingAndTheBandOfTheHeights) {
  namespace tt = terralod::test;
  const std::string dir = std::string(TERRALOD_TEST_TMP) + "/build_heightmap_options";
  fs::create_directories(dir);
  {
    std::ofstream pgm(dir + "/h.pgm", std::ios::binary);
    pgm << "P5\n65 65\n65535\n";
    for (int r = 0; r < 65; ++r)
      for (int c = 0; c < 65; ++c) {
        const int v = 1000 + 40 * c + 25 * r + (c * r) % 17;
        pgm << char(v >> 8) << char(v & 0xff);
      }
  }
  std::ofstream(dir + "/two.vrt")
      << "<VRTDataset rasterXSize=\"65\" rasterYSize=\"65\">\n"
         "  <GeoTransform>500000, 30, 0, 4900000, 0, -30</GeoTransform>\n"
         "  <VRTRasterBand dataType=\"Float32\" band=\"1\"><SimpleSource>\n"
         "    <SourceFilename relativeToVRT=\"1\">h.pgm</SourceFilename><SourceBand>1</SourceBand>\n"
         "  </SimpleSource></VRTRasterBand>\n"
         "  <VRTRasterBand dataType=\"Float32\" band=\"2\"><ComplexSource>\n"
         "    <SourceFilename relativeToVRT=\"1\">h.pgm</SourceFilename><SourceBand>1</SourceBand>\n"
         "    <ScaleOffset>7</ScaleOffset><ScaleRatio>0</ScaleRatio>\n"
         "  </ComplexSource></VRTRasterBand>\n"
         "</VRTDataset>\n";
  const auto json_number = [](const std::string& json, const std::string& key) {
    const std::size_t at = json.find("\"" + key + "\": ");
    return at == std::string::npos ? std::nan("") : std::strtod(json.c_str() + at + key.size() + 4, nullptr);
  };
  const auto info = [&](const std::string& db) {
    const tt::CommandResult r = tt::run_command(tt::quote(TERRALOD_BINARY) + " info " + tt::quote(db));
    EXPECT_EQ(r.status, 0) << r.err;
    return r.out;
  };
  const std::string scaled = dir + "/scaled.db";
  fs::remove(scaled);
  ChildRun r = run_terralod({"build", "--input", dir + "/h.pgm", "--out", scaled, "--block-size", "33",
                             "--vertical-scale", "0.5", "--spacing", "30"});
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string s = info(scaled);
  EXPECT_NE(s.find("spacing 30 m"), std::string::npos) << s;
  EXPECT_NE(s.find("heights = raw * 0.5 + 0 m"), std::string::npos) << s;

  const std::string banded = dir + "/banded.db";
  fs::remove(banded);
  r = run_terralod({"build", "--input", dir + "/two.vrt", "--out", banded, "--block-size", "33"});
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("has 2 bands"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("--band N"), std::string::npos) << r.err;
  r = run_terralod(
      {"build", "--input", dir + "/two.vrt", "--out", banded, "--block-size", "33", "--band", "3"});
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("band 3 was asked for"), std::string::npos) << r.err;
  r = run_terralod(
      {"build", "--input", dir + "/two.vrt", "--out", banded, "--block-size", "33", "--band", "2"});
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string flat = info(banded);
  EXPECT_EQ(json_number(flat, "root_error"), 0.0) << flat;  // the constant band
  const std::string first = dir + "/first.db";
  fs::remove(first);
  r = run_terralod(
      {"build", "--input", dir + "/two.vrt", "--out", first, "--block-size", "33", "--band", "1"});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_GT(json_number(info(first), "root_error"), 8.0);  // the noise of up to 16 m on a plane
}
