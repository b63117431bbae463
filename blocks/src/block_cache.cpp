// Resident block set with a memory budget and LRU eviction; see block_cache.hpp.
#include "terralod/blocks/block_cache.hpp"

#include <algorithm>
#include <cassert>

namespace terralod::blocks {

void BlockCache::insert(std::shared_ptr<const LoadedBlock> block, std::uint64_t frame) {
  assert(block);
  const BlockKey k = block->key;
  erase(k);
  bytes_ += block->memory_bytes;
  peak_ = std::max(peak_, bytes_);
  entries_[k] = Entry{std::move(block), frame, next_order_++};
}

std::shared_ptr<const LoadedBlock> BlockCache::find(BlockKey k) const {
  const auto it = entries_.find(k);
  return it == entries_.end() ? nullptr : it->second.block;
}

void BlockCache::touch(BlockKey k, std::uint64_t frame) {
  const auto it = entries_.find(k);
  if (it != entries_.end()) it->second.last_used = std::max(it->second.last_used, frame);
}

bool BlockCache::erase(BlockKey k) {
  const auto it = entries_.find(k);
  if (it == entries_.end()) return false;
  bytes_ -= it->second.block->memory_bytes;
  entries_.erase(it);
  return true;
}

std::vector<BlockKey> BlockCache::evict(const std::function<bool(BlockKey)>& pinned) {
  std::vector<BlockKey> out;
  if (bytes_ <= opt_.budget_bytes) return out;
  std::vector<std::pair<std::pair<std::uint64_t, std::uint64_t>, BlockKey>> order;
  for (const auto& [k, e] : entries_)
    if (!pinned(k)) order.push_back({{e.last_used, e.order}, k});
  std::sort(order.begin(), order.end());
  for (const auto& [age, k] : order) {
    if (bytes_ <= opt_.budget_bytes) break;
    erase(k);
    out.push_back(k);
  }
  return out;
}

std::vector<BlockKey> BlockCache::keys() const {
  std::vector<BlockKey> k;
  for (const auto& e : entries_) k.push_back(e.first);
  return k;
}

}  // namespace terralod::blocks
