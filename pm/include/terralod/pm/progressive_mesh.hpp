// Progressive mesh of a heightfield built by L-infinity half-edge collapses (one call builds it).
//
// Usage:
//   terralod::pm::Heightfield hf = terralod::pm::generate_terrain();
//   terralod::pm::ProgressiveMesh pm = terralod::pm::ProgressiveMesh::build(hf);
//   terralod::pm::TriangleMesh m = pm.extract(/*max_error=*/2.0);   // metres
//   // m.error_bound <= 2.0 holds at every point of the domain (see ErrorMetric)
//
// Model (seeds/view-dependent-pm-dynamic-loading.txt, section 2): the full-resolution mesh
// M^n is the grid triangulated along (i,j)-(i+1,j+1); collapses c_0, c_1, ... are performed in
// order of increasing L-infinity error (Eq. 1) until nothing can collapse, giving the base
// mesh M^0. The PM stores M^n implicitly (grid + void mask), the collapse sequence, and the
// exact error of each collapse. vsplit_k is the inverse of c_{n-1-k}.
//
// Every collapse is a half-edge collapse u -> w: u disappears, w keeps its position, so every
// vertex is an original sample. Legal collapses: a vertex on the boundary (the grid's border or
// a hole's edge) only collapses into a boundary neighbour where the boundary runs straight
// through it (grid_border.hpp), so the four grid corners never collapse, a border vertex stays
// on its border line and every hole keeps its outline; no triangle flips or degenerates in
// plan view; the link condition holds (OpenMesh is_collapse_ok).
//
// Guarantee of extract(E): because half-edge collapses map faces to faces, the mesh after any
// prefix of the sequence is the image of M^n's faces under "follow the collapses", and every
// triangle of it was formed by some performed collapse whose error was measured over that
// triangle against the full-resolution surface. So the mesh's error is at most the maximum
// error of the performed collapses; extract(E) performs the longest prefix whose maximum is
// <= E and reports that maximum as error_bound.
//
// Memory: 12 bytes per collapse plus the heightfield (8 bytes per sample); build() peaks at
// about 250 bytes per sample (OpenMesh connectivity, heap, error cache).
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/linf_error.hpp"

namespace terralod::pm {

/// One half-edge collapse: sample u moves onto its neighbour w and disappears.
struct Collapse {
  std::uint32_t u = 0;  ///< removed vertex (sample index row * width + col)
  std::uint32_t w = 0;  ///< kept vertex
  double error = 0.0;   ///< L-infinity error of the 1-ring after the collapse, metres
  bool operator==(const Collapse&) const = default;
};

/// Progress callback: fraction in [0,1]; return false to cancel (build() then throws).
using ProgressFn = std::function<bool(double fraction)>;

struct BuildOptions {
  ErrorMetric metric = ErrorMetric::Continuous;
  /// Stop collapsing once the next collapse would exceed this error (metres). The default
  /// collapses until nothing can collapse, which gives the full hierarchy.
  double max_error = 1e300;
  /// Worker threads for the parallel first phase; 0 = hardware concurrency.
  int threads = 0;
  /// true: a grid of >= 257 columns and >= 65536 samples is built as two vertical strips in
  /// parallel, then joined (about twice as fast on two cores; the column between the
  /// strips stays at full resolution up to the strips' common error, a visible line of thin
  /// triangles in view-dependent meshes). false: one greedy sequence over the whole grid, no
  /// such column; block databases use it and build their blocks in parallel instead. Either
  /// way the PM does not depend on `threads`.
  bool parallel_strips = true;
  ProgressFn progress;  ///< optional
};

/// An indexed triangle mesh whose vertices are samples of the heightfield.
struct TriangleMesh {
  std::vector<std::uint32_t> vertices;                  ///< sample indices (row * width + col)
  std::vector<std::array<std::uint32_t, 3>> triangles;  ///< indices into vertices, CCW in (col,row)
  double error_bound = 0.0;                             ///< guaranteed L-infinity error of this mesh, metres
};

class ProgressiveMesh {
 public:
  /// Builds the PM of a heightfield of at least 2 x 2 samples (std::invalid_argument otherwise).
  static ProgressiveMesh build(const Heightfield& hf, const BuildOptions& options = {});
  /// Revision of what build() makes of a heightfield and options: raised whenever they give other
  /// collapses (a changed rule or order), so that a block database begun by one revision is not
  /// finished by another (the build parameters record it: database_build.cpp). 1: until
  /// 2026-12-06 (not recorded); 2: a hole's straight edges thin out like the grid's border.
  static constexpr int kBuilderRevision = 2;

  /// Assembles a PM from its parts (used by the reader); throws std::invalid_argument when the
  /// parts are inconsistent (an index out of range, a vertex removed twice, ...).
  static ProgressiveMesh from_parts(Heightfield hf, ErrorMetric metric, double error_quantum,
                                    std::vector<Collapse> collapses,
                                    std::vector<std::uint32_t> dropped_faces);

  /// The error quantum used for a heightfield: the smallest power of two >= range / 2^24
  /// (range = max - min of the valid heights, at least 1e-9). Errors are rounded up to a
  /// multiple of it, which keeps the bound a guarantee and makes them exact in the file.
  static double error_quantum_for(const Heightfield& hf);

  const Heightfield& heightfield() const { return hf_; }
  ErrorMetric metric() const { return metric_; }
  /// Collapses in the order they were performed (finest first).
  const std::vector<Collapse>& collapses() const { return collapses_; }
  /// Full-resolution faces (see full_face) that could not join the manifold mesh around holes.
  const std::vector<std::uint32_t>& dropped_faces() const { return dropped_faces_; }

  /// Number of vertices of the full-resolution mesh (samples with at least one face).
  std::size_t full_vertex_count() const { return full_vertex_count_; }
  std::size_t base_vertex_count() const { return full_vertex_count_ - collapses_.size(); }
  std::size_t vsplit_count() const { return collapses_.size(); }
  /// Largest collapse error: the error of the base mesh.
  double max_error() const { return prefix_max_.empty() ? 0.0 : prefix_max_.back(); }
  /// Quantum of the stored errors (a power of two, metres): errors are rounded up to it.
  double error_quantum() const { return error_quantum_; }

  /// Number of collapses that extract(max_error) performs.
  std::size_t collapses_within(double max_error) const;
  /// Mesh with guaranteed L-infinity error <= max_error (max_error >= 0). O(samples).
  TriangleMesh extract(double max_error) const;
  /// Mesh after the first `count` collapses (count <= vsplit_count()).
  TriangleMesh extract_after(std::size_t count) const;

  /// Face f of the full-resolution grid: cell (i,j) = f / 2 with i = cell % (W-1), j = cell / (W-1);
  /// f even: (i,j),(i+1,j),(i+1,j+1); f odd: (i,j),(i+1,j+1),(i,j+1). Returns false if absent.
  bool full_face(std::uint32_t f, std::array<std::uint32_t, 3>& out) const;
  std::size_t full_face_slots() const { return 2 * std::size_t(hf_.width() - 1) * (hf_.height() - 1); }

  bool operator==(const ProgressiveMesh& o) const {
    return hf_.samples() == o.hf_.samples() && hf_.mask() == o.hf_.mask() &&
           hf_.transform == o.hf_.transform && metric_ == o.metric_ && error_quantum_ == o.error_quantum_ &&
           collapses_ == o.collapses_ && dropped_faces_ == o.dropped_faces_;
  }

 private:
  void finish();  // derives prefix maxima and counts, validates
  Heightfield hf_;
  ErrorMetric metric_ = ErrorMetric::Continuous;
  std::vector<Collapse> collapses_;
  std::vector<std::uint32_t> dropped_faces_;  // sorted
  std::vector<double> prefix_max_;            // prefix_max_[k] = max error of collapses_[0..k-1]; size n+1
  double error_quantum_ = 0.0;
  std::vector<std::uint8_t> present_;  // 1 for samples that are mesh vertices
  std::size_t full_vertex_count_ = 0;
};

}  // namespace terralod::pm
