// The benchmarks' clocks and quantiles: those of terralod/pm/timing.hpp (ms_since,
// thread_cpu_ms, nearest-rank quantile and median), named in terralod::bench with its Clock.
//
// Usage:
//   const auto t = terralod::bench::Clock::now();
//   ...;
//   samples.push_back(terralod::bench::ms_since(t));
//   const double p99 = terralod::bench::quantile(samples, 0.99), mid = terralod::bench::median(samples);
#pragma once

#include <chrono>

#include "terralod/pm/timing.hpp"

namespace terralod::bench {

using Clock = std::chrono::steady_clock;
using pm::median;
using pm::ms_since;
using pm::quantile;
using pm::thread_cpu_ms;

}  // namespace terralod::bench
