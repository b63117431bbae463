// Independent brute-force checker of a triangle mesh over a heightfield: L-infinity error,
// plan-view coverage, watertightness and vertex validity.
//
// Usage:
//   terralod::test::MeshCheck c = terralod::test::check_mesh(hf, pm.extract(2.0), {pm.dropped_faces()});
//   EXPECT_TRUE(c.ok(/*bound=*/2.0)) << c.describe();
//
// Independence: this file uses only the Heightfield and TriangleMesh types of terralod::pm.
// It shares no code with LInfError or the PM builder: samples are located row by row with
// exact integer spans and exact integer point-in-triangle tests, crossings with a generic exact
// rational point location, and the mesh is compared with the full-resolution surface in long
// double. Every complete mesh check also confirms that every domain sample was found.
//
// Conventions (DESIGN.md): mesh vertices are sample indices row * width + col; triangles are
// CCW in (col,row) index space (orient2d > 0). The full-resolution surface triangulates cell
// (i,j) along the diagonal (i,j)-(i+1,j+1): face 2c is (i,j),(i+1,j),(i+1,j+1) and face 2c+1
// is (i,j),(i+1,j+1),(i,j+1), with c = j * (width-1) + i. The domain is the union of the faces
// whose three corners are valid samples, minus `CheckOptions::excluded_faces`.
//
// What is checked (every count below must be zero for ok()):
//   (a) error: |mesh - sample| at every valid sample in every closed triangle (max_sample_error),
//       and |mesh edge - full-resolution surface| at every crossing of every mesh edge with a
//       vertical, horizontal or diagonal grid edge (max_crossing_error). Both surfaces are
//       piecewise linear, so the larger of the two is the exact L-infinity distance.
//   (b) coverage: no flipped or degenerate triangle; the summed area equals the domain area;
//       the centroid of every domain face lies in exactly one triangle (half-open rule, so a
//       point on a shared edge or vertex counts once); no triangle covers a centroid outside
//       the domain; every valid domain sample lies in some closed triangle.
//   (c) watertight: every mesh edge is used once in each direction (interior) or once in total,
//       and then lies on the domain boundary with the domain on its left; no duplicate
//       vertices or triangles.
//   (d) vertices: indices in range, samples valid; triangle indices in range.
// With (b) and (c) together the mesh is an exact single cover of the domain: positive
// orientation plus matched interior edges make the covering number constant on the domain,
// and the centroid test and the area sum pin it to one.
//
// Cost: O(sum of triangle areas and heights + sum of edge lengths + E log E) time (the face
// centroid test scans bounding boxes), about
// 12 bytes per sample and 16 bytes per half-edge of memory.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/progressive_mesh.hpp"

namespace terralod::test {

struct CheckOptions {
  /// Full-resolution faces (numbering above) that are not part of the domain although their
  /// corners are valid, e.g. ProgressiveMesh::dropped_faces(). Any order.
  std::vector<std::uint32_t> excluded_faces;
  /// Measure the crossings of mesh edges with grid edges (the continuous error).
  bool continuous = true;
};

struct MeshCheck {
  // Sizes.
  std::size_t vertices = 0, triangles = 0;
  std::size_t domain_faces = 0;  ///< full-resolution faces in the domain (its area is half of it)

  // (a) Error, metres.
  double max_sample_error = 0.0;  ///< over valid samples in closed triangles
  int worst_sample_col = -1, worst_sample_row = -1;
  double max_crossing_error = 0.0;  ///< over crossings of mesh edges with grid edges
  double worst_crossing_col = -1, worst_crossing_row = -1;
  std::size_t samples_measured = 0;    ///< (sample, triangle) pairs evaluated
  std::size_t crossings_measured = 0;  ///< crossings evaluated
  /// Rounding allowance of ok(): 0 when every height is an integer (the evaluation is then
  /// exact up to one final rounding), else 1e-12 of the largest |height|.
  double tolerance = 0.0;
  double max_continuous_error() const {
    return max_sample_error > max_crossing_error ? max_sample_error : max_crossing_error;
  }

  // (b) Coverage.
  std::size_t flipped = 0;            ///< orientation < 0
  std::size_t degenerate = 0;         ///< orientation == 0 (including repeated corners)
  std::int64_t area2_sum = 0;         ///< sum of twice the signed triangle areas
  std::int64_t domain_area2 = 0;      ///< twice the domain area (= domain_faces)
  std::size_t uncovered_faces = 0;    ///< domain faces whose centroid no triangle covers
  std::size_t overlapped_faces = 0;   ///< domain faces whose centroid two or more triangles cover
  std::size_t covered_outside = 0;    ///< (triangle, non-domain face centroid) incidences
  std::size_t uncovered_samples = 0;  ///< valid samples of domain faces in no closed triangle
  std::size_t edges_over_holes = 0;   ///< crossings where the full surface is undefined (a hole)

  // (c) Watertightness.
  std::size_t edges = 0, boundary_edges = 0;
  std::size_t non_manifold_edges = 0;       ///< used three times or more
  std::size_t misoriented_edges = 0;        ///< used twice in the same direction
  std::size_t open_edges_off_boundary = 0;  ///< used once but not along the domain boundary
  std::size_t duplicate_vertices = 0, duplicate_triangles = 0;

  // (d) Vertices.
  std::size_t bad_vertices = 0;  ///< sample index out of range or not valid
  std::size_t bad_indices = 0;   ///< triangle corner index out of range of `vertices`

  std::string first_problem;  ///< the first defect found, with its location; empty if none

  /// Everything of (b), (c) and (d) holds.
  bool topology_ok() const;
  /// topology_ok() and the error is at most `bound` (+ tolerance): at the samples, and at the
  /// crossings too when `continuous`.
  bool ok(double bound, bool continuous = true) const;
  /// All numbers, one per line, for failure messages.
  std::string describe() const;
};

MeshCheck check_mesh(const pm::Heightfield& hf, const pm::TriangleMesh& mesh,
                     const CheckOptions& options = {});

/// Error of one triangle on samples s0, s1, s2 (sample indices, either orientation), measured
/// by the same code as check_mesh: `samples` over the valid samples in the closed triangle
/// (0 for a degenerate one), `crossings` over the crossings of its three edges with grid edges
/// (when `continuous`). Lets a test follow a collapse sequence and bound every triangle it
/// creates. Cost: O(bounding-box area + edge lengths).
struct TriangleError {
  double samples = 0.0, crossings = 0.0;
  bool over_hole = false;  ///< an edge crosses a hole (the surface is undefined there)
  double max() const { return samples > crossings ? samples : crossings; }
};
TriangleError triangle_error(const pm::Heightfield& hf, std::uint32_t s0, std::uint32_t s1, std::uint32_t s2,
                             bool continuous = true);
/// The crossings part of triangle_error for one edge (so that a caller can cache edges shared
/// by many triangles). Sets *over_hole when given and the edge crosses a hole.
double edge_error(const pm::Heightfield& hf, std::uint32_t s0, std::uint32_t s1, bool* over_hole = nullptr);

}  // namespace terralod::test
