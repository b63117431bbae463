// The process's own peak resident set, for tests that bound what a step holds in memory: reset
// the kernel's peak counter to the current resident set, run the step, read the peak.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <fstream>
#include <string>

namespace terralod::test {

/// A size field of /proc/self/status ("VmHWM", "VmRSS"), bytes.
inline std::uint64_t status_bytes(const std::string& field) {
  std::ifstream in("/proc/self/status");
  for (std::string line; std::getline(in, line);)
    if (line.rfind(field + ":", 0) == 0) return std::stoull(line.substr(field.size() + 1)) * 1024u;
  ADD_FAILURE() << "/proc/self/status has no " << field << " line";
  return 0;
}

/// The kernel's peak resident set of this process, bytes.
inline std::uint64_t peak_resident() { return status_bytes("VmHWM"); }

/// The current resident set of this process, bytes.
inline std::uint64_t current_resident() { return status_bytes("VmRSS"); }

/// Resets VmHWM to the current resident set (Linux >= 4.0).
inline void reset_peak() {
  std::ofstream out("/proc/self/clear_refs");
  out << "5";
  out.flush();
  ASSERT_TRUE(out.good()) << "/proc/self/clear_refs: cannot reset the peak resident set";
}

}  // namespace terralod::test
