// The process's own peak resident set, for tests that bound what a step holds in memory: reset
// the kernel's peak counter to the current resident set, run the step, read the peak.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <fstream>
#include <string>

namespace terralod::test {

/// The kernel's peak resident set of this process, bytes (VmHWM of /proc/self/status).
inline std::uint64_t peak_resident() {
  std::ifstream in("/proc/self/status");
  for (std::string line; std::getline(in, line);)
    if (line.rfind("VmHWM:", 0) == 0) return std::stoull(line.substr(6)) * 1024u;
  ADD_FAILURE() << "/proc/self/status has no VmHWM line";
  return 0;
}

/// The current resident set of this process, bytes (VmRSS of /proc/self/status).
inline std::uint64_t current_resident() {
  std::ifstream in("/proc/self/status");
  for (std::string line; std::getline(in, line);)
    if (line.rfind("VmRSS:", 0) == 0) return std::stoull(line.substr(6)) * 1024u;
  ADD_FAILURE() << "/proc/self/status has no VmRSS line";
  return 0;
}

/// Resets VmHWM to the current resident set (Linux >= 4.0).
inline void reset_peak() {
  std::ofstream out("/proc/self/clear_refs");
  out << "5";
  out.flush();
  ASSERT_TRUE(out.good()) << "/proc/self/clear_refs: cannot reset the peak resident set";
}

}  // namespace terralod::test
