// The full-resolution mesh of a heightfield without holes, as pm::ProgressiveMesh::extract_after(0)
// gives it: every sample, cell (i,j) split along (i,j)-(i+1,j+1), CCW in (col,row). For render
// tests that draw a terrain without building its PM.
#pragma once

#include <cstdint>

#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/progressive_mesh.hpp"

namespace terralod::test {

inline pm::TriangleMesh full_mesh(const pm::Heightfield& hf) {
  pm::TriangleMesh m;
  const std::uint32_t w = hf.width(), h = hf.height();
  for (std::uint32_t s = 0; s < w * h; ++s) m.vertices.push_back(s);
  for (std::uint32_t j = 0; j + 1 < h; ++j)
    for (std::uint32_t i = 0; i + 1 < w; ++i) {
      const std::uint32_t a = j * w + i, b = a + 1, c = a + w + 1, d = a + w;
      m.triangles.push_back({a, b, c});
      m.triangles.push_back({a, c, d});
    }
  return m;
}

}  // namespace terralod::test
