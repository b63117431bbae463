// Tests of the background loader, the LRU block cache, and loading inside the session: a
// stalled reader never blocks a frame, evicted blocks come back identical, errors name the
// source and the block.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "session_fixture.hpp"
#include "terralod/blocks/block_cache.hpp"
#include "terralod/blocks/block_loader.hpp"
#include "terralod/blocks/terrain_session.hpp"

namespace tb = terralod::blocks;
namespace pm = terralod::pm;
using terralod::test::BlockedTerrain;
using terralod::test::MemoryStore;

namespace {

const BlockedTerrain& terrain() {
  static const BlockedTerrain t = terralod::test::make_blocked_terrain(257, 257, 33, /*seed=*/11, 30.0, 300.0);
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

pm::Camera camera_at(const tb::BlockGrid& g, double col, double row, double z, double yaw = 90) {
  pm::Camera c;
  const auto [x, y] = g.transform().to_world(col, row);
  c.x = x;
  c.y = y;
  c.z = z;
  c.yaw_deg = yaw;
  c.pitch_deg = -25;
  c.far_m = 3e4;
  return c;
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
    EXPECT_TRUE(x.block->pm == pm::decode_pm(blob, "blob"));
    EXPECT_EQ(x.block->blob_bytes, blob.size());
    EXPECT_EQ(x.block->dag->collapse_count(), x.block->pm.collapses().size());
    EXPECT_GT(x.block->memory_bytes, x.block->dag->memory_bytes());
    bytes += blob.size();
  }
  EXPECT_EQ(loader.bytes_read(), bytes);
  EXPECT_EQ(loader.pending(), 0u);
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
      EXPECT_TRUE(r[i].block->pm == pm::decode_pm(t.blobs.at(keys[i]), "blob"));
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

TEST(TerrainSessionLoading, StalledReaderNeverBlocksAFrame) {
  MemoryStore store;
  store.terrain = &terrain();
  store.set_stalled(true);
  tb::SessionOptions opt;
  opt.refinement.morph_seconds = 0.25;
  tb::TerrainSession s(terralod::test::memory_source(store), terrain().grid, terrain().summaries, opt);
  const terralod::test::ReleaseAtExit release{store};
  const pm::Camera cam = camera_at(terrain().grid, 128, 128, 700);
  int frame = 0;
  for (; frame < 30; ++frame) {
    const auto t0 = std::chrono::steady_clock::now();
    const tb::SessionFrameStats& st = s.update(pm::View(cam), frame / 60.0);
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    EXPECT_LT(ms, 2000.0);  // returns although the reader is stalled (a hang would time out)
    EXPECT_EQ(st.resident, 0u);
    EXPECT_EQ(st.stand_ins, st.inner);
    EXPECT_GT(st.loading, 0u);
    EXPECT_EQ(st.refined, 0u);
    EXPECT_GE(st.triangles, 2 * st.active);  // every block as its stand-in (>= two triangles)
    const auto c = terralod::test::check_watertight(s.drawn_mesh(), s.grid(), terralod::test::region_rect(s));
    EXPECT_TRUE(c.ok()) << c.describe();
  }
  // The reader really is stuck inside a read (on a loaded machine the loader thread may only
  // now reach it: wait for it, bounded, rather than race the 30 frames).
  for (int i = 0; i < 1000 && !store.reading.load(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_TRUE(store.reading.load());
  store.set_stalled(false);
  std::size_t swapped = 0;
  for (; frame < 3000; ++frame) {
    const tb::SessionFrameStats& st = s.update(pm::View(cam), frame / 60.0);
    swapped += st.swapped_in;
    if (st.refined == st.inner && st.morphing_blocks == 0) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  EXPECT_EQ(s.stats().refined, s.stats().inner);
  EXPECT_EQ(swapped, s.stats().inner);
  EXPECT_GT(s.stats().bytes_read_total, 0u);
}

TEST(TerrainSessionLoading, EvictedBlocksComeBackIdentical) {
  MemoryStore store;
  store.terrain = &terrain();
  tb::SessionOptions opt;
  opt.prefetch = false;
  opt.cache.budget_bytes = 1;  // evict everything that is not inner at once
  tb::TerrainSession s(terralod::test::memory_source(store), terrain().grid, terrain().summaries, opt);
  auto settle = [&](const pm::Camera& cam, int& frame) {
    for (int i = 0; i < 5000; ++i, ++frame) {
      const tb::SessionFrameStats& st = s.update(pm::View(cam), frame / 60.0);
      if (st.refined == st.inner) return;
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    FAIL() << "blocks never arrived";
  };
  int frame = 0;
  const pm::Camera home = camera_at(terrain().grid, 40, 40, 500), away = camera_at(terrain().grid, 216, 216, 500);
  settle(home, frame);
  const tb::BlockKey k = s.region().centre;
  const std::shared_ptr<const tb::LoadedBlock> first = s.resident(k);
  ASSERT_TRUE(first);
  const pm::TriangleMesh mesh_before = s.selection(k)->mesh();
  settle(away, frame);
  EXPECT_FALSE(s.resident(k)) << "block should have been evicted";
  EXPECT_GT(s.stats().evicted_total, 0u);
  EXPECT_LE(s.stats().resident, s.stats().inner);
  settle(home, frame);
  const std::shared_ptr<const tb::LoadedBlock> again = s.resident(k);
  ASSERT_TRUE(again);
  EXPECT_NE(again.get(), first.get());  // really read again
  EXPECT_TRUE(again->pm == first->pm);
  EXPECT_EQ(again->dag->face_id_count(), first->dag->face_id_count());
  const pm::TriangleMesh mesh_after = s.selection(k)->mesh();
  EXPECT_EQ(mesh_after.vertices, mesh_before.vertices);
  EXPECT_EQ(mesh_after.triangles, mesh_before.triangles);
}

TEST(TerrainSessionLoading, LoaderErrorsAreRethrownByUpdate) {
  BlockedTerrain t = terrain();
  MemoryStore store;
  store.terrain = &t;
  const pm::Camera cam = camera_at(t.grid, 128, 128, 500);
  t.blobs.erase(t.grid.block_at(cam.x, cam.y));
  tb::TerrainSession s(terralod::test::memory_source(store), t.grid, t.summaries, {});
  try {
    for (int f = 0; f < 100000; ++f) {
      s.update(pm::View(cam), f / 60.0);
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), "memory: block (4,4): not in the database");
  }
}

TEST(TerrainSessionLoading, ReadsTheBlockDatabaseOnItsOwnConnection) {
  const BlockedTerrain& t = terrain();
  const std::string path = std::string(TERRALOD_TEST_TMP) + "/session_loading.db";
  for (const char* ext : {"", "-wal", "-shm"}) std::remove((path + ext).c_str());
  tb::DatabaseInfo info;
  info.grid_width = t.hf.width();
  info.grid_height = t.hf.height();
  info.transform = t.hf.transform;
  info.block_size = t.grid.block_size();
  {
    tb::BlockDatabase db = tb::BlockDatabase::create(path, info);
    for (const auto& [k, blob] : t.blobs) db.put_block(k, blob);
    // Without the summaries blob they are computed from the blocks; with it, decoded.
    EXPECT_EQ(tb::read_block_summaries(db, tb::BlockGrid::from_info(db.info())), t.summaries);
    db.put_blob(tb::kBlockSummariesBlob, tb::encode_block_summaries(t.grid, t.summaries));
    EXPECT_EQ(tb::read_block_summaries(db, t.grid), t.summaries);
  }
  tb::TerrainSession s(tb::database_source(path), t.grid, t.summaries, {});
  const pm::Camera cam = camera_at(t.grid, 100, 150, 600);
  for (int f = 0; f < 5000; ++f) {
    const tb::SessionFrameStats& st = s.update(pm::View(cam), f / 60.0);
    if (st.refined == st.inner) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  ASSERT_EQ(s.stats().refined, s.stats().inner);
  std::uint64_t bytes = 0;
  for (tb::BlockKey k : s.resident_keys()) {
    EXPECT_TRUE(s.resident(k)->pm == pm::decode_pm(t.blobs.at(k), "blob"));
    bytes += t.blobs.at(k).size();
  }
  EXPECT_EQ(s.stats().bytes_read_total, bytes);  // each block read once
  // A database that is not there: the loader's error names the file.
  tb::TerrainSession bad(tb::database_source(path + ".missing"), t.grid, t.summaries, {});
  EXPECT_THROW(
      {
        for (int f = 0; f < 5000; ++f) {
          bad.update(pm::View(cam), f / 60.0);
          std::this_thread::sleep_for(std::chrono::milliseconds(1));
        }
      },
      std::runtime_error);
}
