// Resident block set of dynamic loading: the decoded blocks in memory, a memory budget, and
// least-recently-used eviction of the blocks that the frame does not need.
//
// Usage:
//   terralod::blocks::BlockCache cache({/*budget_bytes=*/256u << 20});
//   cache.insert(loaded_block, /*frame=*/f);                 // from BlockLoader::take_results()
//   if (auto b = cache.find({3, 4})) { cache.touch({3, 4}, f); /* use b->dag */ }
//   std::vector<BlockKey> gone = cache.evict([&](BlockKey k) { return region.is_inner(k); });
//
// Contract: blocks are shared_ptr<const LoadedBlock>, so a block evicted while a caller still
// holds it stays valid for that caller; the cache only drops its reference (and its bytes
// from bytes()). evict() removes unpinned blocks, least recently touched first (ties: older
// insertion first), until bytes() <= budget_bytes; pinned blocks are never evicted, so bytes()
// can exceed the budget only by pinned blocks (the caller's active set). Not thread-safe:
// the frame thread owns it.
// Memory: the blocks (LoadedBlock::memory_bytes each) plus ~64 bytes of bookkeeping per block.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <vector>

#include "terralod/blocks/block_loader.hpp"

namespace terralod::blocks {

struct CacheOptions {
  std::size_t budget_bytes = std::size_t(512) << 20;  ///< resident memory target, bytes
};

class BlockCache {
 public:
  explicit BlockCache(const CacheOptions& options = {}) : opt_(options) {}

  const CacheOptions& options() const { return opt_; }
  /// Adds (or replaces) a block; it counts as touched at `frame`.
  void insert(std::shared_ptr<const LoadedBlock> block, std::uint64_t frame);
  /// The block, or null when not resident.
  std::shared_ptr<const LoadedBlock> find(BlockKey k) const;
  bool contains(BlockKey k) const { return entries_.count(k) != 0; }
  /// Marks k as used at `frame` (no-op when not resident).
  void touch(BlockKey k, std::uint64_t frame);
  /// Evicts least-recently-used unpinned blocks until within budget; returns them in order.
  std::vector<BlockKey> evict(const std::function<bool(BlockKey)>& pinned);
  /// Drops k if resident (true if it was).
  bool erase(BlockKey k);

  std::size_t size() const { return entries_.size(); }
  std::size_t bytes() const { return bytes_; }
  std::size_t peak_bytes() const { return peak_; }
  std::vector<BlockKey> keys() const;

 private:
  struct Entry {
    std::shared_ptr<const LoadedBlock> block;
    std::uint64_t last_used = 0, order = 0;
  };
  CacheOptions opt_;
  std::map<BlockKey, Entry> entries_;
  std::size_t bytes_ = 0, peak_ = 0;
  std::uint64_t next_order_ = 0;
};

}  // namespace terralod::blocks
