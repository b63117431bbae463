// The random generator of a randomised test: a fixed seed, printed before the first number is
// drawn, so that a failure can be replayed (STYLE.md, tests: "randomised tests use a fixed,
// printed seed").
//
// Usage:
//   std::mt19937 rng = terralod::test::printed_seed_rng(20240611);   // prints "seed 20240611"
#pragma once

#include <cstdint>
#include <cstdio>
#include <random>

namespace terralod::test {

inline std::mt19937 printed_seed_rng(std::uint32_t seed) {
  std::printf("seed %u\n", unsigned(seed));
  return std::mt19937(seed);
}

}  // namespace terralod::test
