// parallel_for: runs fn(i) for i in [0, n) on a few threads, the way every builder and exporter
// here spreads independent items (blocks, tiles) over the cores.
//
// Usage:
//   terralod::pm::parallel_for(tiles.size(), /*threads=*/0, [&](std::size_t i) { make(tiles[i]); });
//
// Contract: threads <= 0 means std::thread::hardware_concurrency(); never more threads than
// items; items are handed out in order, one at a time (so long items do not leave cores idle).
// The first exception thrown by fn stops handing out items and is rethrown once every thread
// has finished its current item. fn must be safe to call concurrently for distinct i.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace terralod::pm {

inline int thread_count(int threads) {
  return threads > 0 ? threads : int(std::max(1u, std::thread::hardware_concurrency()));
}

template <class F>
void parallel_for(std::size_t n, int threads, F&& fn) {
  const std::size_t k = std::min<std::size_t>(n, std::size_t(thread_count(threads)));
  if (k <= 1) {
    for (std::size_t i = 0; i < n; ++i) fn(i);
    return;
  }
  std::atomic<std::size_t> next{0};
  std::atomic<bool> stop{false};
  std::exception_ptr error;
  std::mutex m;
  auto work = [&] {
    for (std::size_t i; !stop.load() && (i = next.fetch_add(1)) < n;) {
      try {
        fn(i);
      } catch (...) {
        std::lock_guard<std::mutex> lock(m);
        if (!error) error = std::current_exception();
        stop = true;
      }
    }
  };
  std::vector<std::thread> pool;
  for (std::size_t t = 1; t < k; ++t) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
  if (error) std::rethrow_exception(error);
}

}  // namespace terralod::pm
