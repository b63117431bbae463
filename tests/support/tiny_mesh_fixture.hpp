// The tiny heightfield and mesh the mesh writers' tests check by hand (test_mesh_io.cpp,
// test_gltf_writer.cpp), 3 x 2 samples, heights in metres:
//
//   row 0:  s0 = 10.5   s1 = 11.25   s2 = 12
//   row 1:  s3 = 0.1    s4 = -3      s5 = 1e-7
//
// Mesh: vertices {s0, s1, s4, s3} (indices 0..3), triangles (0,1,2) and (0,2,3), both CCW in
// (col,row): orient2d((0,0),(1,0),(1,1)) = +1 and orient2d((0,0),(1,1),(0,1)) = +1; error bound
// 0.75 m. The transform is the identity (a test sets its own).
#pragma once

#include <cstddef>

#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/progressive_mesh.hpp"

namespace terralod::test {

struct TinyMeshFixture {
  pm::Heightfield hf{3, 2};
  pm::TriangleMesh mesh;
  TinyMeshFixture() {
    const double z[6] = {10.5, 11.25, 12.0, 0.1, -3.0, 1e-7};
    for (std::size_t i = 0; i < 6; ++i) hf[i] = z[i];
    mesh.vertices = {0, 1, 4, 3};
    mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
    mesh.error_bound = 0.75;
  }
};

}  // namespace terralod::test
