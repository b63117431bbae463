// Tests of ModLInfT, the L-infinity decimater module for OpenMesh's DecimaterT: hand-derived
// priorities, legality rules, and a full decimation checked by the independent mesh checker.
#include <gtest/gtest.h>

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <vector>

#include "mesh_checker.hpp"
#include "terralod/pm/linf_decimater_module.hpp"
#include "terralod/pm/progressive_mesh.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace {

namespace pm = terralod::pm;
using Mesh = OpenMesh::TriMesh_ArrayKernelT<>;
using Decimater = OpenMesh::Decimater::DecimaterT<Mesh>;
using ModLInf = pm::ModLInfT<Mesh>;
using CollapseInfo = OpenMesh::Decimater::CollapseInfoT<Mesh>;

// The grid as an OpenMesh mesh: vertex k is sample k at (col, row, height); cell (i,j) gives
// (i,j),(i+1,j),(i+1,j+1) and (i,j),(i+1,j+1),(i,j+1) (ProgressiveMesh::full_face's
// convention), skipping faces on holes. Faces OpenMesh refuses are listed in `refused` with
// full_face numbering (the checker's excluded faces).
Mesh grid_to_openmesh(const pm::Heightfield& hf, std::vector<std::uint32_t>* refused = nullptr) {
  Mesh m;
  const int W = hf.width(), H = hf.height();
  for (int r = 0; r < H; ++r)
    for (int c = 0; c < W; ++c) m.add_vertex(Mesh::Point(float(c), float(r), float(hf.at(c, r))));
  for (int j = 0; j + 1 < H; ++j)
    for (int i = 0; i + 1 < W; ++i) {
      const int v00 = j * W + i, v10 = v00 + 1, v01 = v00 + W, v11 = v01 + 1;
      const int faces[2][3] = {{v00, v10, v11}, {v00, v11, v01}};
      for (int k = 0; k < 2; ++k) {
        if (!(hf.valid(std::size_t(faces[k][0])) && hf.valid(std::size_t(faces[k][1])) &&
              hf.valid(std::size_t(faces[k][2]))))
          continue;
        const auto f = m.add_face(Mesh::VertexHandle(faces[k][0]), Mesh::VertexHandle(faces[k][1]),
                                  Mesh::VertexHandle(faces[k][2]));
        if (!f.is_valid() && refused) refused->push_back(std::uint32_t(2 * (j * (W - 1) + i) + k));
      }
    }
  return m;
}

// The decimated mesh as a TriangleMesh of sample indices (faces in OpenMesh's CCW order).
pm::TriangleMesh to_triangle_mesh(const pm::Heightfield& hf, Mesh& m) {
  pm::TriangleMesh out;
  std::vector<std::uint32_t> index(hf.size(), UINT32_MAX);
  for (auto f : m.faces()) {
    if (m.status(f).deleted()) continue;
    std::array<std::uint32_t, 3> t;
    int k = 0;
    for (auto v : m.fv_range(f)) {
      const auto p = m.point(v);
      const std::uint32_t s =
          std::uint32_t(std::lround(p[1])) * std::uint32_t(hf.width()) + std::uint32_t(std::lround(p[0]));
      if (index[s] == UINT32_MAX) index[s] = std::uint32_t(out.vertices.size()), out.vertices.push_back(s);
      t[k++] = index[s];
    }
    out.triangles.push_back(t);
  }
  return out;
}

Mesh::HalfedgeHandle halfedge(const Mesh& m, int from, int to) {
  return m.find_halfedge(Mesh::VertexHandle(from), Mesh::VertexHandle(to));
}

// 3 x 3 zeros with the centre raised by 4 m; see ProgressiveMesh.RaisedCentreKeptUntilItsErrorByHand
// in test_progressive_mesh.cpp for the derivation: removing the centre costs 4 (the mesh is 0
// there); (1,0) -> (0,0) costs 2 (its new edge (0,0)-(2,1) passes (1, 1/2), where the surface is
// 2 and the edge 0) with the continuous metric, and 0 with the sample metric.
//
//   samples: 0 1 2 / 3 4 5 / 6 7 8     (index = row * 3 + col)
TEST(LInfModule, PrioritiesOfTheRaisedCentreByHand) {
  pm::Heightfield hf(3, 3);
  hf.at(1, 1) = 4.0;
  Mesh m = grid_to_openmesh(hf);
  Decimater dec(m);
  ModLInf::Handle h;
  ASSERT_TRUE(dec.add(h));
  ModLInf& mod = dec.module(h);
  mod.set_heightfield(hf);
  ASSERT_TRUE(dec.initialize());
  EXPECT_EQ(mod.collapse_priority(CollapseInfo(m, halfedge(m, 4, 0))), 4.0f);  // centre -> corner
  EXPECT_EQ(mod.collapse_priority(CollapseInfo(m, halfedge(m, 4, 1))), 4.0f);  // centre -> midpoint
  EXPECT_EQ(mod.collapse_priority(CollapseInfo(m, halfedge(m, 1, 0))), 2.0f);  // (1,0) -> (0,0)
  EXPECT_EQ(mod.collapse_priority(CollapseInfo(m, halfedge(m, 1, 2))), 2.0f);  // (1,0) -> (2,0)
  // Illegal: a corner moving, a border vertex leaving its line, and a flip: (1,0) -> (1,1)
  // leaves the border; (0,0) -> anything moves a corner.
  EXPECT_LT(mod.collapse_priority(CollapseInfo(m, halfedge(m, 0, 1))), 0.0f);
  EXPECT_LT(mod.collapse_priority(CollapseInfo(m, halfedge(m, 0, 4))), 0.0f);
  EXPECT_LT(mod.collapse_priority(CollapseInfo(m, halfedge(m, 1, 4))), 0.0f);
  EXPECT_LT(mod.collapse_priority(CollapseInfo(m, halfedge(m, 3, 4))), 0.0f);

  mod.set_heightfield(hf, pm::ErrorMetric::Samples);
  EXPECT_EQ(mod.collapse_priority(CollapseInfo(m, halfedge(m, 1, 0))), 0.0f);
  EXPECT_EQ(mod.collapse_priority(CollapseInfo(m, halfedge(m, 4, 0))), 4.0f);

  // Binary mode: legal (0) within the limit, illegal beyond it.
  mod.set_heightfield(hf);
  mod.set_max_error(2.0);
  EXPECT_TRUE(mod.is_binary());
  EXPECT_EQ(mod.collapse_priority(CollapseInfo(m, halfedge(m, 1, 0))), float(ModLInf::LEGAL_COLLAPSE));
  EXPECT_EQ(mod.collapse_priority(CollapseInfo(m, halfedge(m, 4, 0))), float(ModLInf::ILLEGAL_COLLAPSE));
  mod.set_max_error(1.99);
  EXPECT_EQ(mod.collapse_priority(CollapseInfo(m, halfedge(m, 1, 0))), float(ModLInf::ILLEGAL_COLLAPSE));
  mod.unset_max_error();
  EXPECT_FALSE(mod.is_binary());
  EXPECT_THROW(mod.set_max_error(-1.0), std::invalid_argument);
}

// A plan-view flip, on a hand-made fan around u = (2,2) whose ring is concave at c:
//
//   e (0,4) ------------- d (4,4)        faces (u,a,b) (u,b,c) (u,c,d) (u,d,e) (u,e,a), all CCW
//      |  \              / |
//      |     u (2,2) -- c (3,2)          u -> a: the new faces (a,b,c), (a,c,d), (a,d,e) have
//      |  /          \     |             orient 4*2 = 8, 3*4 - 2*4 = 4 and 16: legal, error 0
//   a (0,0) ------------- b (4,0)          (all heights 0).
//
// u -> d: (u,b,c) becomes (d,b,c) = (4,4),(4,0),(3,2), orient 0*(-2) - (-4)(-1) = -4 < 0: a flip.
TEST(LInfModule, RejectsPlanViewFlip) {
  pm::Heightfield hf(5, 5);
  Mesh m;
  const int coords[6][2] = {{2, 2}, {0, 0}, {4, 0}, {3, 2}, {4, 4}, {0, 4}};
  Mesh::VertexHandle v[6];
  for (int k = 0; k < 6; ++k) v[k] = m.add_vertex(Mesh::Point(float(coords[k][0]), float(coords[k][1]), 0.f));
  for (int k = 1; k <= 5; ++k) ASSERT_TRUE(m.add_face(v[0], v[k], v[k % 5 + 1]).is_valid());
  Decimater dec(m);
  ModLInf::Handle h;
  dec.add(h);
  dec.module(h).set_heightfield(hf);
  ASSERT_TRUE(dec.initialize());
  ModLInf& mod = dec.module(h);
  EXPECT_EQ(mod.collapse_priority(CollapseInfo(m, m.find_halfedge(v[0], v[1]))), 0.0f);
  EXPECT_LT(mod.collapse_priority(CollapseInfo(m, m.find_halfedge(v[0], v[4]))), 0.0f);
}

TEST(LInfModule, InitializeChecksThePoints) {
  pm::Heightfield hf(3, 3);
  {
    Mesh m = grid_to_openmesh(hf);
    Decimater dec(m);
    ModLInf::Handle h;
    dec.add(h);
    EXPECT_THROW(dec.initialize(), std::logic_error);  // no heightfield
  }
  {
    Mesh m = grid_to_openmesh(hf);
    m.set_point(Mesh::VertexHandle(4), Mesh::Point(1.5f, 1.f, 0.f));
    Decimater dec(m);
    ModLInf::Handle h;
    dec.add(h);
    dec.module(h).set_heightfield(hf);
    EXPECT_THROW(dec.initialize(), std::invalid_argument);
  }
}

struct Outcome {
  std::size_t triangles = 0, pm_triangles = 0;
};

// Decimates the grid of `hf` with DecimaterT + ModLInfT to `max_error` and checks the result.
Outcome decimate_and_check(const pm::Heightfield& hf, double max_error, pm::ErrorMetric metric,
                           const char* label) {
  SCOPED_TRACE(label);
  std::vector<std::uint32_t> refused;
  Mesh m = grid_to_openmesh(hf, &refused);
  const auto t0 = std::chrono::steady_clock::now();
  Decimater dec(m);
  ModLInf::Handle h;
  EXPECT_TRUE(dec.add(h));
  dec.module(h).set_heightfield(hf, metric);
  dec.module(h).set_max_error(max_error, /*binary=*/false);
  EXPECT_TRUE(dec.initialize());
  const std::size_t collapses = dec.decimate();
  m.garbage_collection();
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();

  const pm::TriangleMesh tm = to_triangle_mesh(hf, m);
  terralod::test::CheckOptions opt;
  opt.excluded_faces = refused;
  const terralod::test::MeshCheck c = terralod::test::check_mesh(hf, tm, opt);
  EXPECT_TRUE(c.ok(max_error, metric == pm::ErrorMetric::Continuous)) << c.describe();
  const int W = hf.width(), H = hf.height();
  for (std::uint32_t s : {0u, std::uint32_t(W - 1), std::uint32_t((H - 1) * W), std::uint32_t(H * W - 1)})
    if (hf.valid(s)) {
      EXPECT_NE(std::find(tm.vertices.begin(), tm.vertices.end(), s), tm.vertices.end())
          << "corner " << s << " removed";
    }

  pm::BuildOptions bo;
  bo.metric = metric;
  const pm::TriangleMesh pmesh = pm::ProgressiveMesh::build(hf, bo).extract(max_error);
  std::printf(
      "  %s, E = %.1f m: DecimaterT+ModLInfT %zu collapses -> %zu triangles (sample err %.4f, continuous "
      "%.4f, %.0f ms); "
      "ProgressiveMesh::extract %zu triangles\n",
      label, max_error, collapses, tm.triangles.size(), c.max_sample_error, c.max_continuous_error(), ms,
      pmesh.triangles.size());
  return {tm.triangles.size(), pmesh.triangles.size()};
}

// The same greedy L-infinity order through OpenMesh's decimater and through the PM builder:
// both meshes must be within the bound; their sizes should be alike (same kernel, same rules).
TEST(LInfModule, DecimaterOnGeneratedTerrainWithinBound) {
  pm::TerrainOptions to;
  to.width = 33, to.height = 33, to.seed = 1;
  to.relief = 40.0;  // gentle enough for 2 m to remove a good share of the 1089 vertices
  std::printf("  generated 33x33, seed %llu, 40 m relief\n", (unsigned long long)to.seed);
  const pm::Heightfield hf = pm::generate_terrain(to);
  const Outcome o = decimate_and_check(hf, 2.0, pm::ErrorMetric::Continuous, "33x33 continuous");
  EXPECT_LT(o.triangles, 2u * 32u * 32u);
  EXPECT_LE(o.triangles, 2 * o.pm_triangles);
  EXPECT_LE(o.pm_triangles, 2 * o.triangles);
}

TEST(LInfModule, DecimaterWithHolesAndSampleMetric) {
  pm::TerrainOptions to;
  to.width = 33, to.height = 33, to.seed = 5, to.quantize_to_metres = true;
  to.relief = 200.0;
  std::printf("  generated 33x33, seed %llu, quantized, 200 m relief, holes\n", (unsigned long long)to.seed);
  pm::Heightfield hf = pm::generate_terrain(to);
  std::vector<std::uint8_t> mask(hf.size(), 1);
  for (int r = 12; r < 16; ++r)
    for (int c = 10; c < 13; ++c) mask[std::size_t(r) * 33 + c] = 0, hf.at(c, r) = 0.0;
  for (int r = 20; r < 23; ++r)
    mask[std::size_t(r) * 33] = 0, hf.at(0, r) = 0.0;  // a notch in the west border
  hf.set_mask(mask);
  decimate_and_check(hf, 2.0, pm::ErrorMetric::Continuous, "33x33 holes continuous");
  decimate_and_check(hf, 2.0, pm::ErrorMetric::Samples, "33x33 holes samples");
}

}  // namespace
