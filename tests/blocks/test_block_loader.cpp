// Tests of the background loader and the LRU block cache: reads in priority order decoded
// exactly, errors naming the source and the block, the block database as a source on the
// loader's own connection (and its summaries read or computed), eviction beyond the budget.
// Loading inside the frame loop (a stalled reader, eviction and reloads, errors rethrown) is
// tested through the runtime in test_terrain_runtime.cpp.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "block_fixture.hpp"
#include "terrain_runtime_internal.hpp"  // private: the runtime's refinement options
#include "terralod/blocks/block_cache.hpp"
#include "terralod/blocks/block_loader.hpp"

namespace tb = terralod::blocks;
namespace pm = terralod::pm;
using terralod::test::BlockedTerrain;
using terralod::test::MemoryStore;

namespace {

const BlockedTerrain& terrain() {
  static const BlockedTerrain t =
      terralod::test::make_blocked_terrain(257, 257, 33, /*seed=*/11, 30.0, 300.0);
  return t;
}

// Waits (test thread only) until the loader has produced `n` results.
std::vector<tb::LoadResult> wait_results(tb::BlockLoader& l, std::size_t n) {
  std::vector<tb::LoadResult> all;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (all.size() < n && std::chrono::steady_clock::now() < deadline) {
    for (auto& r : l.take_results()) all.push_back(std::move(r));
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return all;
}

// The loaded block is the blob's PM: same metric, heights, transform and collapses in its DAG.
bool is_dag_of(const tb::LoadedBlock& b, const pm::ProgressiveMesh& p) {
  const pm::Heightfield &a = b.dag->heightfield(), &h = p.heightfield();
  if (b.metric != p.metric() || a.width() != h.width() || a.height() != h.height() ||
      !(a.transform == h.transform) || a.samples() != h.samples() || a.mask() != h.mask() ||
      b.dag->collapse_count() != p.collapses().size() || b.dag->full_vertex_count() != p.full_vertex_count())
    return false;
  for (std::uint32_t c = 0; c < p.collapses().size(); ++c)
    if (!(b.dag->collapse(c) == p.collapses()[c])) return false;
  return true;
}

}  // namespace

TEST(BlockLoader, ReadsInPriorityOrderAndDecodesExactly) {
  MemoryStore store;
  store.terrain = &terrain();
  store.set_stalled(true);
  tb::BlockLoader loader(terralod::test::memory_source(store), terrain().grid);
  const terralod::test::ReleaseAtExit release{store};
  // Replaced atomically: the first request the thread takes is the best one, {2,2}.
  loader.set_queue({{{0, 0}, 2.0}, {{2, 2}, 0.0}, {{1, 1}, 1.0}, {{1, 1}, 5.0}});
  EXPECT_EQ(loader.pending(), 3u);  // the duplicate is dropped
  EXPECT_TRUE(loader.busy({1, 1}));
  EXPECT_FALSE(loader.busy({3, 3}));
  store.set_stalled(false);
  const std::vector<tb::LoadResult> r = wait_results(loader, 3);
  ASSERT_EQ(r.size(), 3u);
  EXPECT_EQ(r[0].key, (tb::BlockKey{2, 2}));
  EXPECT_EQ(r[1].key, (tb::BlockKey{1, 1}));
  EXPECT_EQ(r[2].key, (tb::BlockKey{0, 0}));
  std::uint64_t bytes = 0;
  for (const tb::LoadResult& x : r) {
    ASSERT_TRUE(x.block) << x.error;
    const std::vector<std::uint8_t>& blob = terrain().blobs.at(x.key);
    EXPECT_TRUE(is_dag_of(*x.block, pm::decode_pm(blob, "blob")));
    EXPECT_EQ(x.block->blob_bytes, blob.size());
    EXPECT_GT(x.block->memory_bytes, x.block->dag->memory_bytes());
    // What decode_block reserves by default (a refinement with Full geomorphs' lists), and what
    // the runtime reserves (vertical geomorphs, no lists), which README and terrain_runtime.hpp
    // state: about 490 and 460 bytes a vertex (the DAG's boxes held once, no copy of the decoded
    // PM, a refinement at full resolution; test_block_memory checks both against the heap).
    const double nv = double(x.block->dag->full_vertex_count());
    EXPECT_LT(double(x.block->memory_bytes) / nv, 520.0);
    const pm::RefinementOptions runtime = tb::detail::refinement_options(tb::RuntimeOptions{}, 1.0);
    const double runtime_per_vertex =
        double(sizeof(tb::LoadedBlock) + x.block->dag->memory_bytes() +
               pm::SelectiveRefinement::full_memory_bytes(*x.block->dag, runtime)) /
        nv;
    std::printf("block (%d,%d): %.0f bytes a vertex reserved, %.0f by the runtime\n", x.key.col, x.key.row,
                double(x.block->memory_bytes) / nv, runtime_per_vertex);
    EXPECT_LT(runtime_per_vertex, 480.0);
    bytes += blob.size();
  }
  EXPECT_EQ(loader.bytes_read(), bytes);
  EXPECT_EQ(loader.pending(), 0u);
}

// Several threads, each with its own source: every block is read once and decodes exactly, and
// the counts cover every thread's read in progress.
TEST(BlockLoader, SeveralThreadsReadEveryBlockOnce) {
  MemoryStore store;
  store.terrain = &terrain();
  store.set_stalled(true);
  tb::BlockLoader loader(terralod::test::memory_source(store), terrain().grid, {}, /*threads=*/3);
  const terralod::test::ReleaseAtExit release{store};
  std::vector<tb::BlockLoader::Request> req;
  for (const auto& [k, blob] : terrain().blobs) req.push_back({k, double(req.size())});
  loader.set_queue(req);
  EXPECT_EQ(loader.pending(), req.size());
  // Whichever requests the threads took (and stall in), a new queue neither drops nor repeats.
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  loader.set_queue(req);
  EXPECT_EQ(loader.pending(), req.size()) << "requests in flight are neither dropped nor queued twice";
  store.set_stalled(false);
  const std::vector<tb::LoadResult> r = wait_results(loader, req.size());
  ASSERT_EQ(r.size(), req.size());
  std::set<tb::BlockKey> seen;
  std::uint64_t bytes = 0;
  for (const tb::LoadResult& x : r) {
    ASSERT_TRUE(x.block) << x.error;
    EXPECT_TRUE(seen.insert(x.key).second) << "block read twice";
    const std::vector<std::uint8_t>& blob = terrain().blobs.at(x.key);
    EXPECT_TRUE(is_dag_of(*x.block, pm::decode_pm(blob, "blob")));
    bytes += blob.size();
  }
  EXPECT_EQ(loader.bytes_read(), bytes);
  EXPECT_EQ(loader.pending(), 0u);
  EXPECT_THROW(tb::BlockLoader(terralod::test::memory_source(store), terrain().grid, {}, 0),
               std::invalid_argument);
}

// held_bytes: a block being read counts at its request's bytes, a finished one not yet taken
// at its LoadedBlock::memory_bytes, and nothing once taken; a database source adds its
// connection's bound (cache limit and structures) from the moment the loader is constructed.
TEST(BlockLoader, HeldBytesFollowABlockFromReadToTaken) {
  MemoryStore store;
  store.terrain = &terrain();
  store.set_stalled(true);
  tb::BlockLoader loader(terralod::test::memory_source(store), terrain().grid);
  const terralod::test::ReleaseAtExit release{store};
  EXPECT_EQ(loader.held_bytes(), 0u);
  loader.set_queue({{{1, 1}, 0.0, 0.0, 12345}, {{2, 2}, 1.0, 0.0, 777}});
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (loader.held_bytes() != 12345 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  EXPECT_EQ(loader.held_bytes(), 12345u) << "the block being read counts at its request's bytes";
  EXPECT_TRUE(loader.holds({1, 1}));
  EXPECT_FALSE(loader.holds({2, 2})) << "a queued block is not held";
  store.set_stalled(false);
  while (loader.finished() < 2 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  ASSERT_EQ(loader.finished(), 2u);
  EXPECT_TRUE(loader.holds({2, 2}));
  const std::size_t held = loader.held_bytes();
  const std::vector<tb::LoadResult> r = loader.take_results();
  ASSERT_EQ(r.size(), 2u);
  ASSERT_TRUE(r[0].block && r[1].block);
  EXPECT_EQ(held, r[0].block->memory_bytes + r[1].block->memory_bytes);
  EXPECT_EQ(loader.held_bytes(), 0u);
  EXPECT_FALSE(loader.holds({1, 1}));

  const std::string path = std::string(TERRALOD_TEST_TMP) + "/loader_held.db";
  for (const char* ext : {"", "-wal", "-shm"}) std::remove((path + ext).c_str());
  tb::DatabaseInfo info;
  info.grid_width = terrain().hf.width();
  info.grid_height = terrain().hf.height();
  info.transform = terrain().hf.transform;
  info.block_size = terrain().grid.block_size();
  { tb::BlockDatabase::create(path, info).put_block({0, 0}, terrain().blobs.at({0, 0})); }
  tb::BlockLoader db_loader(tb::database_source(path), terrain().grid, {}, /*threads=*/2);
  const std::size_t bound = tb::BlockDatabase::open(path).memory_bytes();
  EXPECT_GT(bound, std::size_t(128) << 10);
  // The loader's connections limit their cache to 256 kB: two of them, each with its structures.
  EXPECT_EQ(db_loader.held_bytes(), 2 * ((std::size_t(256) << 10) + (std::size_t(128) << 10)));
}

TEST(BlockLoader, ErrorsNameTheSourceAndTheBlock) {
  BlockedTerrain t = terrain();
  t.blobs.erase({3, 4});
  t.blobs[{4, 4}].resize(10);  // truncated blob
  MemoryStore store;
  store.terrain = &t;
  tb::BlockLoader loader(terralod::test::memory_source(store), t.grid);
  loader.set_queue({{{3, 4}, 0}, {{4, 4}, 1}});
  const std::vector<tb::LoadResult> r = wait_results(loader, 2);
  ASSERT_EQ(r.size(), 2u);
  EXPECT_FALSE(r[0].block);
  EXPECT_EQ(r[0].error, "memory: block (3,4): not in the database");
  EXPECT_FALSE(r[1].block);
  EXPECT_EQ(r[1].error.rfind("memory: block (4,4): ", 0), 0u) << r[1].error;
}

TEST(BlockLoader, ReadsTheBlockDatabaseOnItsOwnConnection) {
  // database_source: the loader thread opens the database read-only on its own connection and
  // reads exactly the blobs written; a database that is not there is an error naming the file.
  // read_block_summaries: computed from the blocks without the summaries blob, decoded with it.
  const BlockedTerrain& t = terrain();
  const std::string path = std::string(TERRALOD_TEST_TMP) + "/loader_database.db";
  for (const char* ext : {"", "-wal", "-shm"}) std::remove((path + ext).c_str());
  tb::DatabaseInfo info;
  info.grid_width = t.hf.width();
  info.grid_height = t.hf.height();
  info.transform = t.hf.transform;
  info.block_size = t.grid.block_size();
  {
    tb::BlockDatabase db = tb::BlockDatabase::create(path, info);
    for (const auto& [k, blob] : t.blobs) db.put_block(k, blob);
    EXPECT_EQ(tb::read_block_summaries(db, tb::BlockGrid::from_info(db.info())), t.summaries);
    db.put_blob(tb::kBlockSummariesBlob, tb::encode_block_summaries(t.grid, t.summaries));
    EXPECT_EQ(tb::read_block_summaries(db, t.grid), t.summaries);
  }
  const std::vector<tb::BlockKey> keys{{0, 0}, {3, 5}, {7, 7}};
  {
    tb::BlockLoader loader(tb::database_source(path), t.grid);
    std::vector<tb::BlockLoader::Request> q;
    for (tb::BlockKey k : keys) q.push_back({k, double(q.size())});
    loader.set_queue(q);
    const std::vector<tb::LoadResult> r = wait_results(loader, keys.size());
    ASSERT_EQ(r.size(), keys.size());
    std::uint64_t bytes = 0;
    for (std::size_t i = 0; i < r.size(); ++i) {
      EXPECT_EQ(r[i].key, keys[i]);
      ASSERT_TRUE(r[i].block) << r[i].error;
      EXPECT_TRUE(is_dag_of(*r[i].block, pm::decode_pm(t.blobs.at(keys[i]), "blob")));
      bytes += t.blobs.at(keys[i]).size();
    }
    EXPECT_EQ(loader.bytes_read(), bytes);  // each block read once
  }
  tb::BlockLoader bad(tb::database_source(path + ".missing"), t.grid);
  bad.set_queue({{{1, 1}, 0}});
  const std::vector<tb::LoadResult> r = wait_results(bad, 1);
  ASSERT_EQ(r.size(), 1u);
  EXPECT_FALSE(r[0].block);
  EXPECT_NE(r[0].error.find(path + ".missing"), std::string::npos) << r[0].error;
}

TEST(BlockCache, EvictsLeastRecentlyUsedUnpinnedBlocksBeyondTheBudget) {
  // Three blocks of 100 bytes, budget 250: inserting the third evicts the least recently used
  // unpinned one.
  auto block = [](int c) {
    auto b = std::make_shared<tb::LoadedBlock>();
    b->key = {c, 0};
    b->memory_bytes = 100;
    return std::shared_ptr<const tb::LoadedBlock>(b);
  };
  tb::BlockCache cache({/*budget_bytes=*/250});
  cache.insert(block(0), 1);
  cache.insert(block(1), 2);
  cache.touch({0, 0}, 3);  // block 1 is now the least recently used
  cache.insert(block(2), 4);
  EXPECT_EQ(cache.bytes(), 300u);
  EXPECT_EQ(cache.peak_bytes(), 300u);
  auto nothing_pinned = [](tb::BlockKey) { return false; };
  EXPECT_EQ(cache.evict(nothing_pinned), (std::vector<tb::BlockKey>{{1, 0}}));
  EXPECT_EQ(cache.bytes(), 200u);
  EXPECT_TRUE(cache.evict(nothing_pinned).empty());  // within budget
  // Pinned blocks stay even beyond the budget.
  cache.insert(block(3), 5);
  cache.insert(block(4), 6);
  const auto gone = cache.evict([](tb::BlockKey k) { return k.col != 2; });
  EXPECT_EQ(gone, (std::vector<tb::BlockKey>{{2, 0}}));
  EXPECT_EQ(cache.bytes(), 300u);
  EXPECT_FALSE(cache.find({2, 0}));
  EXPECT_TRUE(cache.find({4, 0}));
}
