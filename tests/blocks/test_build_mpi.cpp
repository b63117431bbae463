// `mpirun -np N terralod build` (apps/build_mpi.hpp) with the real Open MPI launcher: the
// database equals the single-process build's, block for block and byte for byte (blocks, their
// records, the tree, the stand-in summaries); a rank killed with SIGKILL mid-build ends the job
// and leaves a database that the same command resumes to that same content. Fails, never skips,
// without mpirun or without MPI built into terralod (scripts/install-deps.sh installs Open MPI).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "run_command.hpp"
#include "terralod/blocks/block_database.hpp"

namespace {

namespace fs = std::filesystem;
namespace tb = terralod::blocks;
using terralod::test::quote;
using terralod::test::run_command;

const fs::path& tmp() { return terralod::test::process_temp_dir("build-mpi"); }

// Open MPI refuses to start as root without these (CI containers run as root).
const std::string kMpirun = "OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 mpirun";

std::string cli() { return quote(TERRALOD_BINARY); }

void require_mpi() {
#ifndef TERRALOD_HAVE_MPI
  FAIL() << "terralod was built without MPI: install openmpi-bin libopenmpi-dev (scripts/install-deps.sh)";
#endif
  const auto r = run_command("command -v mpirun");
  ASSERT_EQ(r.status, 0) << "mpirun is not on the PATH (openmpi-bin)";
}

/// A fractal input of w x h samples (written once per size).
fs::path input(int w, int h) {
  const fs::path p = tmp() / ("in_" + std::to_string(w) + "x" + std::to_string(h) + ".tif");
  if (!fs::exists(p)) {
    const auto r = run_command(cli() + " testdem --fractal " + std::to_string(w) + "x" + std::to_string(h) +
                               " --seed 5 --out " + quote(p.string()));
    EXPECT_EQ(r.status, 0) << r.err;
  }
  return p;
}

std::string build_args(const fs::path& in, const fs::path& out) {
  return " build --input " + quote(in.string()) + " --out " + quote(out.string()) +
         " --block-size 33 --strategy grid,tin";
}

/// Everything a build writes except its wall time: blocks, meta records, blobs.
void expect_same_content(const fs::path& a_path, const fs::path& b_path) {
  const tb::BlockDatabase a = tb::BlockDatabase::open(a_path.string()),
                          b = tb::BlockDatabase::open(b_path.string());
  EXPECT_TRUE(b.check_integrity().ok);
  ASSERT_EQ(a.blocks(), b.blocks());
  for (tb::BlockKey k : a.blocks()) ASSERT_EQ(a.read_block(k), b.read_block(k)) << k.col << "," << k.row;
  EXPECT_EQ(a.blob_names(), b.blob_names());
  for (const std::string& blob : a.blob_names()) EXPECT_EQ(a.read_blob(blob), b.read_blob(blob)) << blob;
  EXPECT_EQ(a.meta_keys(), b.meta_keys());
  for (const std::string& key : a.meta_keys()) {
    if (key == "build_seconds") continue;
    EXPECT_EQ(a.get_meta(key), b.get_meta(key)) << key;
  }
  EXPECT_EQ(a.info(), b.info());
}

}  // namespace

TEST(BuildMpi, TwoAndFourRanksEqualTheSingleProcessBuild) {
  ASSERT_NO_FATAL_FAILURE(require_mpi());
  const fs::path in = input(385, 321);  // 12 x 10 blocks of 33
  const fs::path ref = tmp() / "ref.db", two = tmp() / "np2.db", four = tmp() / "np4.db";
  auto r = run_command(cli() + build_args(in, ref) + " --threads 2");
  ASSERT_EQ(r.status, 0) << r.err;
  r = run_command(kMpirun + " -np 2 " + cli() + build_args(in, two) + " --threads 1");
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("120 built now"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("2 MPI ranks"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("read  "), r.out.rfind("read  ")) << "only rank 0 prints\n" << r.out;
  expect_same_content(ref, two);
  r = run_command(kMpirun + " -np 4 --oversubscribe " + cli() + build_args(in, four) + " --threads 1");
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("4 MPI ranks"), std::string::npos) << r.out;
  expect_same_content(ref, four);
  // Run again: everything is there; every rank is told so and the job ends.
  r = run_command(kMpirun + " -np 2 " + cli() + build_args(in, two) + " --threads 1");
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("0 built now, 120 resumed"), std::string::npos) << r.out;
  // Other options on an existing database: rank 0's error ends the whole job, naming the file.
  r = run_command(kMpirun + " -np 2 " + cli() + build_args(in, two) + " --threads 1 --patch 2");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.err.find(two.string()), std::string::npos) << r.err;
}

TEST(BuildMpi, AKilledRankLeavesADatabaseThatResumesToTheSameContent) {
  ASSERT_NO_FATAL_FAILURE(require_mpi());
  const fs::path in = input(1025, 769);  // 32 x 24 blocks of 33: a few seconds
  const fs::path ref = tmp() / "kill_ref.db", db = tmp() / "killed.db";
  auto r = run_command(cli() + build_args(in, ref) + " --threads 2");
  ASSERT_EQ(r.status, 0) << r.err;
  // mpirun in the background, with a mark in its environment to find its ranks by.
  const std::string mark = "TERRALOD_MPI_TEST=" + std::to_string(::getpid());
  const fs::path log = tmp() / "killed.log";
  const pid_t launcher = fork();
  if (launcher == 0) {
    const std::string cmd = mark + " " + kMpirun + " -np 2 " + cli() + build_args(in, db) + " --threads 1 >" +
                            quote(log.string()) + " 2>&1";
    execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  // Wait for some blocks, then SIGKILL rank 1.
  pid_t rank1 = -1;
  std::size_t blocks_then = 0;
  for (int i = 0; i < 600 && rank1 < 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    if (!fs::exists(db)) continue;
    try {
      blocks_then = tb::BlockDatabase::open(db.string()).blocks().size();
    } catch (const std::exception&) {
      continue;  // still being created
    }
    if (blocks_then < 40) continue;
    for (const auto& e : fs::directory_iterator("/proc")) {
      const std::string env = terralod::test::slurp(e.path() / "environ");
      if (env.find(mark) != std::string::npos && env.find("OMPI_COMM_WORLD_RANK=1") != std::string::npos) {
        rank1 = pid_t(std::stol(e.path().filename().string()));
        break;
      }
    }
  }
  ASSERT_GT(rank1, 0) << "rank 1 not found (or the build ended before 40 blocks)\n"
                      << terralod::test::slurp(log);
  ASSERT_EQ(kill(rank1, SIGKILL), 0);
  int st = 0;
  waitpid(launcher, &st, 0);
  EXPECT_FALSE(WIFEXITED(st) && WEXITSTATUS(st) == 0) << "the job went on without rank 1\n"
                                                      << terralod::test::slurp(log);
  {
    const tb::BlockDatabase part = tb::BlockDatabase::open(db.string());
    EXPECT_TRUE(part.check_integrity().ok);
    EXPECT_GE(part.blocks().size(), blocks_then);
    EXPECT_LT(part.blocks().size(), 32u * 24u) << "killed after the last block: nothing left to resume";
    EXPECT_FALSE(part.get_meta("build_complete").has_value());
  }
  r = run_command(kMpirun + " -np 2 " + cli() + build_args(in, db) + " --threads 1");
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_NE(r.out.find(" resumed)"), std::string::npos) << r.out;
  expect_same_content(ref, db);
}
