// PM build options with a fixed thread count, for tests that time or stress the build: the PM
// never depends on the count, the time does.
//
// Usage:
//   const auto p = terralod::pm::ProgressiveMesh::build(hf, terralod::test::build_threads(1));
#pragma once

#include "terralod/pm/progressive_mesh.hpp"

namespace terralod::test {

inline pm::BuildOptions build_threads(int n) {
  pm::BuildOptions o;
  o.threads = n;
  return o;
}

}  // namespace terralod::test
