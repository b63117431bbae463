// Test support for block loading: blocked generated terrains (block PMs encoded as in a block
// database, and summaries with their stand-ins, one kind or a mix of kinds) and an in-memory
// block source with controllable latency (a stalled reader), for BlockLoader and for
// TerrainRuntime's `blocks` source.
//
// Usage:
//   const terralod::test::BlockedTerrain t = terralod::test::make_blocked_terrain(257, 257, 33, /*seed=*/11);
//   terralod::test::MemoryStore store;
//   store.terrain = &t;                 // the blobs read; must outlive the readers
//   store.latency_frames = 2;           // each read waits until advance_frame() was called twice
//   terralod::blocks::BlockLoader loader(terralod::test::memory_source(store), t.grid);
//   const terralod::test::ReleaseAtExit release{store};   // after the loader: unblocks its last read
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "terralod/blocks/active_region.hpp"
#include "terralod/blocks/block_loader.hpp"
#include "terralod/blocks/partition.hpp"
#include "terralod/pm/pm_io.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace terralod::test {

/// A terrain cut into blocks: the blobs (pm::encode_pm of each block PM) and summaries.
/// Stand-ins: blocks::StandinOptions{} (the database default), or with a list of options, block
/// (col,row) uses list[(col + 2 row) % size] so that neighbours differ.
struct BlockedTerrain {
  pm::Heightfield hf;
  blocks::BlockGrid grid;
  std::map<blocks::BlockKey, std::vector<std::uint8_t>> blobs;
  std::vector<blocks::BlockSummary> summaries;
};

inline BlockedTerrain block_terrain(pm::Heightfield hf, int block_size,
                                    const std::vector<blocks::StandinOptions>& standins = {});

/// A generated terrain (heights in whole metres) cut into blocks.
inline BlockedTerrain make_blocked_terrain(int width, int height, int block_size, std::uint64_t seed,
                                           double spacing = 30.0, double relief = 1200.0,
                                           const std::vector<blocks::StandinOptions>& standins = {}) {
  pm::TerrainOptions to;
  to.width = width;
  to.height = height;
  to.seed = seed;
  to.spacing = spacing;
  to.relief = relief;
  to.quantize_to_metres = true;
  return block_terrain(pm::generate_terrain(to), block_size, standins);
}

/// Cuts `hf` into blocks (partition.hpp) and builds every block's PM.
inline BlockedTerrain block_terrain(pm::Heightfield hf, int block_size,
                                    const std::vector<blocks::StandinOptions>& standins) {
  const int width = hf.width(), height = hf.height();
  BlockedTerrain t;
  t.hf = std::move(hf);
  t.grid = blocks::BlockGrid(width, height, block_size, t.hf.transform);
  const blocks::BlockLayout layout = blocks::partition(width, height, block_size);
  t.summaries.resize(t.grid.block_count());
  for (blocks::BlockKey k : layout.keys()) {
    const pm::ProgressiveMesh pm = blocks::build_block_pm(t.hf, layout.rect(k));
    t.blobs[k] = pm::encode_pm(pm);
    const blocks::StandinOptions o = standins.empty()
                                         ? blocks::StandinOptions{}
                                         : standins[std::size_t(k.col + 2 * k.row) % standins.size()];
    t.summaries[t.grid.index(k)] = blocks::summarize_block(pm, k, o);
  }
  return t;
}

/// Shared state of MemorySource objects: the blobs, a gate that can stall every read until
/// the frame counter reaches a value, and counters.
struct MemoryStore {
  const BlockedTerrain* terrain = nullptr;
  std::mutex mutex;
  std::condition_variable cv;
  bool stalled = false;              ///< reads wait while true
  std::uint64_t frame = 0;           ///< advanced by the test's frame loop
  std::uint64_t latency_frames = 0;  ///< each read waits until `frame` has advanced this much
  bool released = false;             ///< reads never wait once set (see ReleaseAtExit)
  std::atomic<int> reads{0};
  std::atomic<bool> reading{false};

  void set_stalled(bool s) {
    {
      std::lock_guard l(mutex);
      stalled = s;
    }
    cv.notify_all();
  }
  void release() {
    {
      std::lock_guard l(mutex);
      released = true;
    }
    cv.notify_all();
  }
  void advance_frame() {
    {
      std::lock_guard l(mutex);
      ++frame;
    }
    cv.notify_all();
  }
};

/// Declared after the loader or runtime that reads from `store`: releases every waiting read
/// before the loader thread is joined (a loader waits for the read in progress when it stops).
struct ReleaseAtExit {
  MemoryStore& store;
  ~ReleaseAtExit() { store.release(); }
};

/// A block source over store.terrain's blobs: each read first waits at the store's gate, then
/// returns the blob or throws DatabaseError "memory: block (c,r): not in the database".
class MemorySource final : public blocks::BlockSource {
 public:
  explicit MemorySource(MemoryStore& s) : s_(&s) {}
  std::vector<std::uint8_t> read(blocks::BlockKey k) override {
    s_->reading = true;
    {
      std::unique_lock l(s_->mutex);
      const std::uint64_t until = s_->frame + s_->latency_frames;
      s_->cv.wait(l, [&] { return s_->released || (!s_->stalled && s_->frame >= until); });
    }
    ++s_->reads;
    s_->reading = false;
    const auto it = s_->terrain->blobs.find(k);
    if (it == s_->terrain->blobs.end())
      throw blocks::DatabaseError("memory", "block (" + std::to_string(k.col) + "," + std::to_string(k.row) +
                                                "): not in the database");
    return it->second;
  }
  std::string name() const override { return "memory"; }

 private:
  MemoryStore* s_;
};

inline blocks::BlockSourceFactory memory_source(MemoryStore& s) {
  return [&s]() -> std::unique_ptr<blocks::BlockSource> { return std::make_unique<MemorySource>(s); };
}

}  // namespace terralod::test
