// Timing and order statistics shared by the benchmark programs: wall-clock and thread CPU
// milliseconds, and nearest-rank quantiles of the measured samples.
//
// Usage:
//   const auto t = terralod::bench::Clock::now();
//   ...;
//   samples.push_back(terralod::bench::ms_since(t));
//   const double p99 = terralod::bench::quantile(samples, 0.99), mid = terralod::bench::median(samples);
//
// Contract: quantile(v, q) is the nearest-rank quantile, the ceil(q n)-th smallest of the n
// samples (the smallest for q = 0, the largest for q = 1), q in [0, 1]; 0 for an empty v.
// median(v) is quantile(v, 0.5): the lower of the two middle samples when n is even.
// thread_cpu_ms() is the calling thread's CPU time (not advanced while it waits for a core).
#pragma once

#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <vector>

namespace terralod::bench {

using Clock = std::chrono::steady_clock;

/// Milliseconds of wall-clock time since `t`.
inline double ms_since(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

/// CPU time of the calling thread, milliseconds.
inline double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return double(ts.tv_sec) * 1e3 + double(ts.tv_nsec) * 1e-6;
}

/// Nearest-rank quantile, q in [0, 1]; 0 for no samples.
inline double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const std::size_t k = std::size_t(std::ceil(q * double(v.size())));
  return v[std::min(v.size() - 1, k == 0 ? 0 : k - 1)];
}

inline double median(const std::vector<double>& v) { return quantile(v, 0.5); }

}  // namespace terralod::bench
