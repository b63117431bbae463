// build_database with RemoteBuilders (tree_builder.hpp), in process: what `mpirun terralod
// build` (apps/build_mpi.cpp) relies on, run here under the sanitizers too. Blocks built by a
// remote builder on threads of its own are written exactly as local ones; a remote that fails
// stops the build with its error and leaves a database that resumes; a delivered block that is
// not one of the terrain's is refused.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "run_command.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace {

namespace fs = std::filesystem;
namespace tb = terralod::blocks;
namespace pm = terralod::pm;

const fs::path& tmp() { return terralod::test::process_temp_dir("remote-builder"); }

pm::Heightfield terrain() {
  pm::TerrainOptions o;
  o.width = 161, o.height = 129, o.seed = 3, o.quantize_to_metres = true;
  pm::Heightfield hf = pm::generate_terrain(o);
  hf.source = "generated";
  return hf;
}

tb::DatabaseBuildOptions options() {
  tb::DatabaseBuildOptions o;
  o.block_size = 17;  // 10 x 8 blocks
  o.threads = 1;
  o.tree.levels = {tb::StrategyChoice::Grid, tb::StrategyChoice::Tin};
  return o;
}

/// A remote builder with `threads` threads of its own, each claiming and building until none
/// is left; `fail_after` > 0: the remote throws after delivering that many blocks.
tb::RemoteBuilder remote(const pm::Heightfield& hf, const tb::DatabaseBuildOptions& opt, int threads,
                         std::atomic<int>& delivered, int fail_after = 0) {
  return [&hf, opt, threads, &delivered, fail_after](const auto& claim, const auto& deliver) {
    std::mutex m;  // claim and deliver are called from several threads, as MPI ranks would
    std::vector<std::thread> pool;
    std::exception_ptr error;
    for (int t = 0; t < threads; ++t)
      pool.emplace_back([&] {
        try {
          for (;;) {
            std::optional<tb::BlockKey> k;
            {
              std::lock_guard<std::mutex> lock(m);
              k = claim();
            }
            if (!k) break;
            tb::BuiltBlock b = tb::build_block(hf, *k, opt);
            std::lock_guard<std::mutex> lock(m);
            if (fail_after > 0 && delivered >= fail_after) throw std::runtime_error("remote rank lost");
            deliver(std::move(b));
            ++delivered;
          }
        } catch (...) {
          std::lock_guard<std::mutex> lock(m);
          if (!error) error = std::current_exception();
        }
      });
    for (auto& t : pool) t.join();
    if (error) std::rethrow_exception(error);
  };
}

void expect_same_content(const fs::path& a_path, const fs::path& b_path) {
  const tb::BlockDatabase a = tb::BlockDatabase::open(a_path.string()),
                          b = tb::BlockDatabase::open(b_path.string());
  ASSERT_EQ(a.blocks(), b.blocks());
  for (tb::BlockKey k : a.blocks()) EXPECT_EQ(a.read_block(k), b.read_block(k));
  EXPECT_EQ(a.blob_names(), b.blob_names());
  for (const std::string& blob : a.blob_names()) EXPECT_EQ(a.read_blob(blob), b.read_blob(blob)) << blob;
  for (const std::string& key : a.meta_keys()) {
    if (key == "build_seconds") continue;
    EXPECT_EQ(a.get_meta(key), b.get_meta(key)) << key;
  }
}

}  // namespace

TEST(RemoteBuilder, RemoteBlocksAreWrittenExactlyAsLocalOnes) {
  const pm::Heightfield hf = terrain();
  const fs::path local = tmp() / "local.db", shared = tmp() / "shared.db";
  tb::build_database(hf, local.string(), options());
  std::atomic<int> delivered{0};
  tb::DatabaseBuildOptions opt = options();
  opt.remote_builders.push_back(remote(hf, opt, 2, delivered));
  const tb::DatabaseSummary s = tb::build_database(hf, shared.string(), opt);
  EXPECT_TRUE(s.complete);
  EXPECT_EQ(s.blocks_built, 80u);
  EXPECT_GT(delivered.load(), 0) << "the remote built nothing";
  std::printf("80 blocks: %d built by the remote's 2 threads, %d by the local one\n", delivered.load(),
              80 - delivered.load());
  expect_same_content(local, shared);
  // Nothing left to build: the remote is still run (it must tell its builders to stop).
  tb::DatabaseBuildOptions again = options();
  bool ran = false;
  again.remote_builders.push_back([&](const auto& claim, const auto&) {
    ran = true;
    EXPECT_FALSE(claim().has_value());
  });
  EXPECT_EQ(tb::build_database(hf, shared.string(), again).blocks_built, 0u);
  EXPECT_TRUE(ran);
}

TEST(RemoteBuilder, AFailingRemoteStopsTheBuildAndTheDatabaseResumes) {
  const pm::Heightfield hf = terrain();
  const fs::path local = tmp() / "local2.db", db = tmp() / "failing.db";
  tb::build_database(hf, local.string(), options());
  std::atomic<int> delivered{0};
  tb::DatabaseBuildOptions opt = options();
  opt.remote_builders.push_back(remote(hf, opt, 2, delivered, /*fail_after=*/5));
  try {
    tb::build_database(hf, db.string(), opt);
    FAIL() << "the remote's error was lost";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("remote rank lost"), std::string::npos) << e.what();
  }
  {
    const tb::BlockDatabase part = tb::BlockDatabase::open(db.string());
    EXPECT_TRUE(part.check_integrity().ok);
    EXPECT_FALSE(part.get_meta("build_complete").has_value());
  }
  EXPECT_TRUE(tb::build_database(hf, db.string(), options()).complete);
  expect_same_content(local, db);
}

TEST(RemoteBuilder, ABlockOutsideTheTerrainIsRefused) {
  const pm::Heightfield hf = terrain();
  tb::DatabaseBuildOptions opt = options();
  opt.remote_builders.push_back([&](const auto& claim, const auto& deliver) {
    if (claim()) {
      tb::BuiltBlock b = tb::build_block(hf, {0, 0}, opt);
      b.key = {10, 0};
      deliver(std::move(b));
    }
  });
  try {
    tb::build_database(hf, (tmp() / "outside.db").string(), opt);
    FAIL() << "a block outside the 10 x 8 layout was accepted";
  } catch (const tb::BuildError& e) {
    EXPECT_NE(std::string(e.what()).find("not a block of this terrain"), std::string::npos) << e.what();
  }
  EXPECT_THROW(tb::build_block(hf, {0, 8}, opt), tb::BuildError);
}

// The writer writes a delivered block without decoding its PM; what it does check, a bad
// summary record or build record, stops the build with an error naming the block.
TEST(RemoteBuilder, ABadSummaryOrRecordFromARemoteIsRefused) {
  const pm::Heightfield hf = terrain();
  const tb::DatabaseBuildOptions base = options();
  const tb::BuiltBlock good = tb::build_block(hf, {2, 1}, base);
  const std::vector<std::function<void(tb::BuiltBlock&)>> spoil = {
      [](tb::BuiltBlock& b) { b.summary.resize(10); },
      [](tb::BuiltBlock& b) { b.summary[32] = 9; },  // the record's stand-in kind
      [](tb::BuiltBlock& b) { b.base_error = std::nan(""); },
      [](tb::BuiltBlock& b) { b.pm.clear(); },
  };
  for (std::size_t i = 0; i < spoil.size(); ++i) {
    SCOPED_TRACE("spoiled " + std::to_string(i));
    tb::DatabaseBuildOptions opt = base;
    opt.remote_builders.push_back([&](const auto& claim, const auto& deliver) {
      if (!claim()) return;
      tb::BuiltBlock b = good;
      spoil[i](b);
      deliver(std::move(b));
    });
    try {
      tb::build_database(hf, (tmp() / ("spoiled" + std::to_string(i) + ".db")).string(), opt);
      FAIL() << "a spoiled block was written";
    } catch (const tb::BuildError& e) {
      EXPECT_NE(std::string(e.what()).find("block (2,1) from a remote builder"), std::string::npos)
          << e.what();
    }
  }
}
