// On-demand texture patches: a FIFO of loads served by worker threads, an LRU budget
// (dynamic-3d-maps-texture-layers.txt section 3.1). Memory: resident pixels + O(keys).
#include "terralod/render/texture_cache.hpp"

#include <cassert>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <exception>
#include <map>
#include <mutex>
#include <thread>
#include <vector>

namespace terralod::render {

namespace {
enum class State : std::uint8_t { Queued, Loading, Ready, Failed, Evicted };
struct Entry {
  State state = State::Queued;
  std::shared_ptr<const RgbaImage> pixels;
  std::uint64_t last_used = 0;  // frame number
  std::uint64_t tick = 0;       // LRU order inside a frame
};
}  // namespace

struct TextureCache::Impl {
  TextureLoader loader;
  TextureCacheOptions options;
  mutable std::mutex mutex;
  std::condition_variable work_cv;
  mutable std::condition_variable idle_cv;
  std::map<TextureKey, Entry> entries;
  std::deque<TextureKey> queue;
  std::vector<std::thread> workers;
  TextureCacheStats stats;
  std::string last_error;
  std::uint64_t tick = 0;
  bool stopping = false;

  std::shared_ptr<const RgbaImage> request_locked(const TextureKey& k) {
    ++stats.requests;
    Entry& e = entries[k];      // a new key starts Queued
    e.last_used = stats.frame;  // also for loads: what arrives is in use in the frame that asked
    if (e.state == State::Ready) {
      e.tick = ++tick;
      return e.pixels;
    }
    if (e.state == State::Evicted || (e.state == State::Queued && e.tick == 0)) {
      e.state = State::Queued;
      e.tick = ++tick;  // marks "in the queue"
      queue.push_back(k);
      ++stats.pending;
      work_cv.notify_one();
    }
    return nullptr;
  }

  void evict_locked() {
    while (stats.resident_bytes > options.budget_bytes) {
      auto victim = entries.end();
      for (auto it = entries.begin(); it != entries.end(); ++it)
        if (it->second.state == State::Ready && it->second.last_used < stats.frame &&
            (victim == entries.end() || it->second.last_used < victim->second.last_used ||
             (it->second.last_used == victim->second.last_used && it->second.tick < victim->second.tick)))
          victim = it;
      if (victim == entries.end()) return;  // everything resident is in use this frame
      stats.resident_bytes -= victim->second.pixels->rgba.size();
      --stats.resident;
      ++stats.evictions;
      victim->second.pixels.reset();
      victim->second.state = State::Evicted;
    }
  }

  void work() {
    std::unique_lock lock(mutex);
    for (;;) {
      work_cv.wait(lock, [&] { return stopping || !queue.empty(); });
      if (stopping) return;
      const TextureKey k = queue.front();
      queue.pop_front();
      entries[k].state = State::Loading;
      lock.unlock();
      std::shared_ptr<const RgbaImage> px;
      std::string error;
      try {
        px = std::make_shared<const RgbaImage>(loader(k));
      } catch (const std::exception& ex) {
        error = ex.what();
      } catch (...) {
        error = "unknown exception";
      }
      lock.lock();
      Entry& e = entries[k];
      --stats.pending;
      if (px) {
        e.state = State::Ready;
        e.pixels = std::move(px);
        e.tick = ++tick;
        stats.resident_bytes += e.pixels->rgba.size();
        ++stats.resident;
        ++stats.loads;
        stats.loaded_bytes += e.pixels->rgba.size();
        evict_locked();
      } else {
        e.state = State::Failed;
        ++stats.failures;
        last_error =
            "texture layer " + std::to_string(k.layer) + " node " + std::to_string(k.node) + ": " + error;
      }
      idle_cv.notify_all();
    }
  }
};

TextureCache::TextureCache(TextureLoader loader, const TextureCacheOptions& options)
    : impl_(std::make_unique<Impl>()) {
  assert(loader && options.threads >= 1);
  impl_->loader = std::move(loader);
  impl_->options = options;
  for (int i = 0; i < options.threads; ++i) impl_->workers.emplace_back([this] { impl_->work(); });
}

TextureCache::~TextureCache() {
  {
    std::lock_guard lock(impl_->mutex);
    impl_->stopping = true;
  }
  impl_->work_cv.notify_all();
  for (std::thread& t : impl_->workers) t.join();
}

void TextureCache::begin_frame() {
  std::lock_guard lock(impl_->mutex);
  ++impl_->stats.frame;
  impl_->evict_locked();
}

std::shared_ptr<const RgbaImage> TextureCache::request(const TextureKey& key) {
  std::lock_guard lock(impl_->mutex);
  return impl_->request_locked(key);
}

std::shared_ptr<const RgbaImage> TextureCache::resolve(const TextureTree& tree, const TextureKey& key,
                                                       TextureKey* used) {
  std::lock_guard lock(impl_->mutex);
  for (TextureKey k = key; k.node >= 0; k.node = tree.parent_patch(k.node)) {
    assert(tree.has_patch(k.node));
    if (auto px = impl_->request_locked(k)) {
      if (used) *used = k;
      return px;
    }
  }
  if (used) *used = TextureKey{key.layer, -1};
  return nullptr;
}

bool TextureCache::resident(const TextureKey& key) const {
  std::lock_guard lock(impl_->mutex);
  auto it = impl_->entries.find(key);
  return it != impl_->entries.end() && it->second.state == State::Ready;
}

TextureCacheStats TextureCache::stats() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->stats;
}

std::string TextureCache::last_error() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->last_error;
}

bool TextureCache::wait_idle(int timeout_ms) const {
  std::unique_lock lock(impl_->mutex);
  return impl_->idle_cv.wait_for(lock, std::chrono::milliseconds(timeout_ms),
                                 [&] { return impl_->stats.pending == 0; });
}

}  // namespace terralod::render
