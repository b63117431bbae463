// Timing and order statistics shared by the tools, the runtime's reports and the benchmarks:
// milliseconds since a steady-clock time point, the calling thread's CPU time, and nearest-rank
// quantiles of a sample.
//
// Usage:
//   const auto t0 = std::chrono::steady_clock::now();
//   work();
//   times.push_back(terralod::pm::ms_since(t0));
//   std::printf("median %.2f ms, p95 %.2f ms\n", terralod::pm::median(times),
//               terralod::pm::quantile(times, 0.95));
//
// Contract:
//   ms_since(t)     milliseconds from t to now on the steady clock (>= 0).
//   thread_cpu_ms() the calling thread's CPU time in milliseconds (POSIX CLOCK_THREAD_CPUTIME_ID):
//                   not advanced while the thread waits for a core, so differences measure its
//                   own cost on a loaded machine.
//   quantile(v, q)  the nearest-rank q-quantile of v, q in [0, 1]: the smallest element x of v
//                   such that at least q * v.size() elements are <= x (q = 0 gives the minimum,
//                   q = 1 the maximum). v is taken by value and sorted: O(n log n). An empty v
//                   gives 0 (a report over no frames shows zeros rather than failing).
//   median(v)       quantile(v, 0.5): the lower middle element for an even count.
//   peak_resident_bytes() the process's peak resident set so far (getrusage's ru_maxrss, which
//                   Linux keeps in KiB), bytes: what a build reports as its peak memory.
//   heap_in_use_bytes() (glibc only) the bytes malloc has handed out and not taken back, over
//                   every arena (mallinfo2: in-use chunks plus mmapped ones): what the runtime's
//                   memory accounts are checked against.
#pragma once

#if defined(__GLIBC__)
#include <malloc.h>
#endif
#include <sys/resource.h>
#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace terralod::pm {

inline double ms_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
}

inline std::uint64_t peak_resident_bytes() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return std::uint64_t(ru.ru_maxrss) * 1024u;
}

#if defined(__GLIBC__)
inline double heap_in_use_bytes() {
  const struct mallinfo2 m = mallinfo2();
  return double(m.uordblks) + double(m.hblkhd);
}
#endif

inline double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return double(ts.tv_sec) * 1e3 + double(ts.tv_nsec) * 1e-6;
}

inline double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const std::size_t k = std::size_t(std::ceil(q * double(v.size())));
  return v[std::min(v.size() - 1, k == 0 ? 0 : k - 1)];
}

inline double median(std::vector<double> v) { return quantile(std::move(v), 0.5); }

}  // namespace terralod::pm
