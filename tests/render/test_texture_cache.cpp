// Tests of on-demand texture loading: a deliberately slow loader never blocks a frame and the
// parent's texture is drawn meanwhile; after loading the child's is used; LRU eviction under
// a budget; failing loads. Multi-threaded: runs under ThreadSanitizer in CI (scripts/test.sh).
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <stdexcept>

#include "terralod/render/texture_cache.hpp"

namespace {

using namespace terralod::render;
namespace pm = terralod::pm;
using Clock = std::chrono::steady_clock;

// A chain root 0 -> 1 -> 2 over [0,64]^2 with a 64 x 64 image and max texture size 16:
// levels 64 (1 m), 32, 16; root uses level 2, node 1 ([0,32]x[0,32], 32 texels) level 1,
// node 2 ([0,16]x[0,16]) level 0.
TextureTree chain_tree() {
  std::vector<PatchDomain> d(3);
  const double side[3] = {64, 32, 16};
  for (int i = 0; i < 3; ++i) {
    d[i].id = i;
    d[i].parent = i - 1;
    if (i < 2) d[i].children = {i + 1};
    d[i].bbox = pm::Box{{0, 0, 0}, {side[i], side[i], 0}};
  }
  return TextureTree(d, pyramid_levels(64, 64, 16), GeoRect{0, 0, 64, 64}, TextureConstraints{16, false});
}

// Pixels that say which node they are: a 16 x 16 image filled with the node id.
RgbaImage tagged(std::int64_t node) {
  RgbaImage img(16, 16);
  for (std::size_t i = 0; i < img.rgba.size(); ++i) img.rgba[i] = std::uint8_t(node);
  return img;
}

// A gate the test opens: loads of gated nodes wait on it (a deliberately slow loader).
struct Gate {
  std::mutex m;
  std::condition_variable cv;
  bool open = false;
  void wait() {
    std::unique_lock l(m);
    cv.wait(l, [&] { return open; });
  }
  void release() {
    {
      std::lock_guard l(m);
      open = true;
    }
    cv.notify_all();
  }
};

TEST(TextureCache, SlowLoaderNeverBlocksAFrameAndTheParentIsUsedMeanwhile) {
  const TextureTree tree = chain_tree();
  Gate gate;
  std::atomic<int> loads{0};
  TextureCache cache([&](const TextureKey& k) {
    ++loads;
    if (k.node == 2) gate.wait();  // the child's load hangs until released
    return tagged(k.node);
  });
  // Frame 0: nothing resident yet: no texture, and the call returns at once.
  cache.begin_frame();
  TextureKey used;
  EXPECT_EQ(cache.resolve(tree, {0, 1}, &used), nullptr);
  EXPECT_EQ(used.node, -1);
  ASSERT_TRUE(cache.wait_idle(10000));  // node 1 and root loaded
  // Frames 1..20 want node 2 whose load hangs: each frame gets node 1's pixels (its parent
  // patch) without waiting.
  double worst_ms = 0;
  for (int f = 0; f < 20; ++f) {
    cache.begin_frame();
    const auto t0 = Clock::now();
    const auto px = cache.resolve(tree, {0, 2}, &used);
    worst_ms = std::max(worst_ms, std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
    ASSERT_NE(px, nullptr);
    EXPECT_EQ(used.node, 1);
    EXPECT_EQ(px->rgba[0], 1);
  }
  EXPECT_LT(worst_ms, 100.0) << "a frame waited for the loader";
  EXPECT_EQ(cache.stats().pending, 1u);
  EXPECT_FALSE(cache.resident({0, 2}));
  gate.release();
  ASSERT_TRUE(cache.wait_idle(10000));
  cache.begin_frame();
  const auto px = cache.resolve(tree, {0, 2}, &used);
  ASSERT_NE(px, nullptr);
  EXPECT_EQ(used.node, 2);
  EXPECT_EQ(px->rgba[0], 2);
  EXPECT_EQ(loads.load(), 3);  // each patch loaded once although requested every frame
  EXPECT_EQ(cache.stats().loads, 3u);
}

TEST(TextureCache, EvictsLeastRecentlyUsedOverTheBudget) {
  // Budget: two 16 x 16 textures (2 * 1024 bytes). Keys of layer 0, nodes 10, 11, 12.
  TextureCacheOptions o;
  o.budget_bytes = 2 * 1024;
  TextureCache cache([](const TextureKey& k) { return tagged(k.node); }, o);
  cache.begin_frame();
  cache.request({0, 10});
  ASSERT_TRUE(cache.wait_idle(10000));
  cache.begin_frame();
  cache.request({0, 11});
  ASSERT_TRUE(cache.wait_idle(10000));
  cache.begin_frame();
  ASSERT_NE(cache.request({0, 11}), nullptr);  // 11 used this frame, 10 last used 2 frames ago
  cache.request({0, 12});
  ASSERT_TRUE(cache.wait_idle(10000));
  EXPECT_FALSE(cache.resident({0, 10}));  // the least recently used went
  EXPECT_TRUE(cache.resident({0, 11}));
  EXPECT_TRUE(cache.resident({0, 12}));
  TextureCacheStats s = cache.stats();
  EXPECT_EQ(s.evictions, 1u);
  EXPECT_EQ(s.resident_bytes, 2048u);
  // Everything in use this frame is kept even over budget; the next frame trims it.
  cache.request({0, 10});
  ASSERT_TRUE(cache.wait_idle(10000));
  cache.request({0, 10});
  EXPECT_EQ(cache.stats().resident_bytes, 3 * 1024u);
  cache.begin_frame();
  EXPECT_EQ(cache.stats().resident_bytes, 2 * 1024u);
  // An evicted key reloads on request.
  EXPECT_EQ(cache.stats().loads, 4u);
}

TEST(TextureCache, FailedLoadsKeepTheParentAndNameTheKey) {
  const TextureTree tree = chain_tree();
  TextureCache cache([](const TextureKey& k) -> RgbaImage {
    if (k.node == 2) throw std::runtime_error("tile is corrupt");
    return tagged(k.node);
  });
  TextureKey used;
  cache.resolve(tree, {3, 2}, &used);
  ASSERT_TRUE(cache.wait_idle(10000));
  cache.begin_frame();
  ASSERT_NE(cache.resolve(tree, {3, 2}, &used), nullptr);
  EXPECT_EQ(used.node, 1);
  ASSERT_TRUE(cache.wait_idle(10000));  // a failed key is not retried
  EXPECT_EQ(cache.stats().failures, 1u);
  EXPECT_NE(cache.last_error().find("layer 3 node 2: tile is corrupt"), std::string::npos)
      << cache.last_error();
}

TEST(TextureCache, ManyThreadsManyKeys) {
  // 4 workers, 200 keys requested from the frame thread while loads finish concurrently;
  // every key ends resident exactly once (no lost or duplicated loads).
  TextureCacheOptions o;
  o.threads = 4;
  std::atomic<int> loads{0};
  TextureCache cache(
      [&](const TextureKey& k) {
        ++loads;
        return tagged(k.node % 256);
      },
      o);
  for (int round = 0; round < 3; ++round) {
    cache.begin_frame();
    for (int k = 0; k < 200; ++k) cache.request({1, k});
  }
  ASSERT_TRUE(cache.wait_idle(20000));
  EXPECT_EQ(loads.load(), 200);
  for (int k = 0; k < 200; ++k) EXPECT_TRUE(cache.resident({1, k})) << k;
}

}  // namespace
