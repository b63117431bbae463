// TextureCache: texture patches loaded or computed on worker threads on first request, kept
// under a memory budget with least-recently-used eviction; a frame never waits for a load.
//
// Usage:
//   terralod::render::TextureCache cache(
//       [&](const terralod::render::TextureKey& k) {          // runs on a worker thread
//         return pyramid.read(tree.patch(k.node).rect);        // or read a tile from the database
//       },
//       {/*budget_bytes=*/256u << 20});
//   cache.begin_frame();
//   for (auto node : selected) {
//     terralod::render::TextureKey used;
//     auto px = cache.resolve(tree, {/*layer=*/0, tree.owner(node)}, &used);  // never blocks
//     if (px) draw(node, used, *px);      // used.node == the wanted node once it has loaded,
//   }                                     // an ancestor's patch until then
//
// Contract (dynamic-3d-maps-texture-layers.txt section 3.1: "as long as the thread is not
// finished, the texture of the parent texture patch is used instead"):
//   - request(k) returns the pixels when resident, else queues one load of k (once; repeated
//     requests of a pending key do nothing) and returns nullptr at once.
//   - resolve(tree, k, used) requests k and, until it is resident, walks up the texture tree
//     (TextureTree::parent_patch) requesting each ancestor and returns the first resident
//     one; *used tells which key was returned. nullptr when no ancestor is resident yet.
//   - The loader runs on `threads` worker threads (>= 1), never on the caller's; it must be
//     safe to call concurrently when threads > 1. A loader that throws marks the key failed
//     (stats().failures, last_error()); it is not retried and its ancestors keep being used.
//   - Eviction: whenever the resident bytes (4 per pixel) exceed budget_bytes, the least
//     recently used entries not used in the current frame (since begin_frame) are dropped;
//     the budget may be exceeded by what the current frame uses. Evicted pixels stay valid
//     for whoever holds the shared_ptr.
//   - All members are thread-safe. The destructor stops the workers after their current
//     load (queued loads are dropped) and joins them.
//   - Memory: the resident pixels + ~100 bytes per key ever requested.
#pragma once

#include <compare>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "terralod/render/rgba_image.hpp"
#include "terralod/render/texture_tree.hpp"

namespace terralod::render {

/// A texture patch of one layer: the node owning it in that layer's texture tree.
struct TextureKey {
  int layer = 0;
  std::int64_t node = -1;
  auto operator<=>(const TextureKey&) const = default;
};

using TextureLoader = std::function<RgbaImage(const TextureKey&)>;

struct TextureCacheOptions {
  std::size_t budget_bytes = std::size_t(256) << 20;  ///< resident pixel bytes allowed
  int threads = 1;                                    ///< worker threads, >= 1
};

struct TextureCacheStats {
  std::size_t resident_bytes = 0, resident = 0;  ///< pixels held, entries held
  std::size_t requests = 0;                      ///< request() calls (resolve counts each key it asks for)
  std::size_t loads = 0;                         ///< loads finished
  std::size_t loaded_bytes = 0;                  ///< pixel bytes of those loads (what a renderer uploads)
  std::size_t failures = 0, evictions = 0;
  std::size_t pending = 0;  ///< queued or running loads
  std::uint64_t frame = 0;  ///< begin_frame() calls
};

class TextureCache {
 public:
  explicit TextureCache(TextureLoader loader, const TextureCacheOptions& options = {});
  ~TextureCache();
  TextureCache(const TextureCache&) = delete;
  TextureCache& operator=(const TextureCache&) = delete;

  /// Starts a frame: entries used from now on are protected from eviction until the next call.
  void begin_frame();
  std::shared_ptr<const RgbaImage> request(const TextureKey& key);
  std::shared_ptr<const RgbaImage> resolve(const TextureTree& tree, const TextureKey& key, TextureKey* used);
  /// True when the key's pixels are resident (does not touch LRU order or queue anything).
  bool resident(const TextureKey& key) const;
  TextureCacheStats stats() const;
  std::string last_error() const;
  /// Blocks until no load is queued or running, or `timeout_ms` passed; true if idle. For
  /// tools and tests (a frame never calls it).
  bool wait_idle(int timeout_ms) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace terralod::render
