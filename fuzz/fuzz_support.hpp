// Shared by the fuzz targets: how a broken invariant is reported (abort under libFuzzer, an
// exception when tests/stress/test_fuzz_regressions.cpp replays the target).
#pragma once

#include <cstdio>
#include <cstdlib>
#include <string>

namespace terralod::fuzz {

/// Thrown instead of aborting when the target is compiled with TERRALOD_FUZZ_REPLAY (the
/// regression test); deliberately not a std::exception, so that no harness catch swallows it.
struct Finding {
  std::string what;
};

[[noreturn]] inline void finding(const char* target, const std::string& what) {
#ifdef TERRALOD_FUZZ_REPLAY
  throw Finding{std::string(target) + ": " + what};
#else
  std::fprintf(stderr, "%s: %s\n", target, what.c_str());
  std::abort();
#endif
}

}  // namespace terralod::fuzz
