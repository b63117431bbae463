// OpenMesh decimater module that ranks half-edge collapses of a grid mesh by their exact
// L-infinity error (Eq. 1 of the view-dependent PM paper), for use with OpenMesh's DecimaterT.
//
// Usage:
//   using Mesh = OpenMesh::TriMesh_ArrayKernelT<>;
//   Mesh mesh = ...;  // one vertex per sample, point = (col, row, height); faces CCW in (col,row)
//   OpenMesh::Decimater::DecimaterT<Mesh> decimater(mesh);
//   terralod::pm::ModLInfT<Mesh>::Handle h;
//   decimater.add(h);
//   decimater.module(h).set_heightfield(hf);        // required before initialize()
//   decimater.module(h).set_max_error(2.0, /*binary=*/false);   // metres; optional
//   decimater.initialize();
//   decimater.decimate();
//   mesh.garbage_collection();
//
// This is the standard, slow route (OpenMesh re-measures every candidate of every vertex
// whose ring changed, with no caching). ProgressiveMesh::build runs the same kernel and the
// same legality rules (the boundary rule is grid_border.hpp's, shared) in its own loop and
// records the collapse sequence; use it unless you need OpenMesh's decimater framework (other
// modules, observers, your own mesh type). The product's user of this module is the reference
// build route through that framework: build_with_decimater (openmesh_build.hpp), which records
// every collapse DecimaterT performs into a ProgressiveMesh, and with it
// `terralod pm --decimater openmesh`.
//
// Contract:
//   - Every vertex with a face has x = column and y = row as exact integers, at a valid sample
//     of the heightfield (initialize() throws std::invalid_argument otherwise); z is not read:
//     heights come from the heightfield, which must outlive the module.
//   - For the collapse v0 -> v1 (ci.v0 removed, ci.v1 kept) the priority is
//     E = max over the new triangles (v0's faces other than ci.fl and ci.fr, with v0 replaced
//     by v1) of LInfError::triangle, i.e. Eq. 1 over the part of v1's new 1-ring that changed
//     (the rest of the mesh, and so of the ring, is untouched by the collapse).
//   - ILLEGAL_COLLAPSE when v0 is on the boundary (the grid's border or a hole's edge) and
//     v0 -> v1 is not a boundary edge or the boundary is not straight through v0
//     (grid_border.hpp: corners never move, a border vertex stays on its border line, a hole
//     keeps its shape); when a new triangle would flip or degenerate in plan view; and when
//     E > max_error (see set_max_error).
//   - Binary mode (set_max_error(e) with binary = true, like ModQuadricT::set_max_err):
//     LEGAL_COLLAPSE (0) when E <= e. Non-binary (the default): E itself, as a float rounded
//     up so that the priority never understates the error.
//   - collapse_error(ci) is E itself as a double (-1 when illegal), for recording collapses.
//   - OpenMesh's own checks (link condition, boundary rules) run in DecimaterT before the
//     module is asked.
// Memory: none per vertex; O(valence) scratch per call.
#pragma once

#include <OpenMesh/Tools/Decimater/ModBaseT.hh>
#include <algorithm>
#include <cfloat>
#include <cmath>
#include <stdexcept>
#include <string>

#include "terralod/pm/grid_border.hpp"
#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/linf_error.hpp"

namespace terralod::pm {

template <class MeshT>
class ModLInfT : public OpenMesh::Decimater::ModBaseT<MeshT> {
 public:
  DECIMATING_MODULE(ModLInfT, MeshT, LInf);

  /// Constructed by DecimaterT::add(); non-binary, no error limit, no heightfield yet.
  explicit ModLInfT(MeshT& mesh) : Base(mesh, false) {}

  /// The heightfield the mesh samples (must outlive the module) and the error measure.
  void set_heightfield(const Heightfield& hf, ErrorMetric metric = ErrorMetric::Continuous) {
    hf_ = &hf;
    metric_ = metric;
  }

  /// Collapses whose error exceeds `max_error` (metres, >= 0) are illegal. With binary = true
  /// the module only accepts or rejects, and another module must rank the collapses.
  void set_max_error(double max_error, bool binary = true) {
    if (!(max_error >= 0.0)) throw std::invalid_argument("ModLInfT: max_error must be >= 0");
    max_error_ = max_error;
    Base::set_binary(binary);
  }
  void unset_max_error() {
    max_error_ = kNoLimit;
    Base::set_binary(false);
  }
  double max_error() const { return max_error_; }

  void initialize() override {
    if (!hf_) throw std::logic_error("ModLInfT: set_heightfield() must be called before initialize()");
    MeshT& m = Base::mesh();
    for (auto v : m.vertices()) {
      if (m.status(v).deleted() || m.is_isolated(v)) continue;  // e.g. samples on holes, unused
      const auto p = m.point(v);
      const double x = double(p[0]), y = double(p[1]);
      if (x != std::floor(x) || y != std::floor(y) || x < 0 || y < 0 || x >= hf_->width() ||
          y >= hf_->height())
        throw std::invalid_argument("ModLInfT: vertex " + std::to_string(v.idx()) + " at (" +
                                    std::to_string(x) + ", " + std::to_string(y) +
                                    ") is not a sample of the " + std::to_string(hf_->width()) + " x " +
                                    std::to_string(hf_->height()) + " heightfield");
      if (!hf_->valid(int(x), int(y)))
        throw std::invalid_argument("ModLInfT: vertex " + std::to_string(v.idx()) +
                                    " sits on a hole of the heightfield");
    }
  }

  float collapse_priority(const CollapseInfo& ci) override {
    const double e = collapse_error(ci);
    if (e < 0.0) return float(Base::ILLEGAL_COLLAPSE);
    if (Base::is_binary()) return float(Base::LEGAL_COLLAPSE);
    float prio = float(e);
    if (double(prio) < e) prio = std::nextafter(prio, FLT_MAX);
    return prio;
  }

  /// E of the collapse v0 -> v1 in metres, exactly (the priority before its rounding to a
  /// float), or -1 when the collapse is illegal (see the contract; OpenMesh's own checks are
  /// not repeated here). build_with_decimater records it for every collapse performed.
  double collapse_error(const CollapseInfo& ci) {
    constexpr double kIllegal = -1.0;
    MeshT& m = Base::mesh();
    const GridPoint p0 = grid_point(ci.p0), p1 = grid_point(ci.p1);
    // A boundary vertex moves only into a boundary neighbour, where the boundary is straight
    // through it (grid_border.hpp): then it has exactly two boundary neighbours.
    if (m.is_boundary(ci.v0)) {
      if (!m.is_boundary(m.edge_handle(ci.v0v1))) return kIllegal;
      GridPoint ends[2];
      int n_ends = 0;
      for (auto h : m.voh_range(ci.v0)) {
        if (!m.is_boundary(h) && !m.is_boundary(m.opposite_halfedge_handle(h))) continue;
        if (n_ends == 2) return kIllegal;
        ends[n_ends++] = grid_point(m.point(m.to_vertex_handle(h)));
      }
      if (n_ends != 2 || !boundary_straight_at(ends[0], p0, ends[1])) return kIllegal;
    }
    // The new triangles: v0's faces except fl and fr, with v0 replaced by v1. Each is measured
    // in full (no cutoff): a rejection only needs one triangle above max_error, and a full
    // measurement cannot be mistaken for a partial one.
    const LInfError err(*hf_, metric_);
    double e = 0.0;
    for (auto h : m.voh_range(ci.v0)) {
      const auto f = m.face_handle(h);
      if (!f.is_valid() || f == ci.fl || f == ci.fr) continue;
      const auto hn = m.next_halfedge_handle(h);
      const GridPoint a = grid_point(m.point(m.to_vertex_handle(h))),
                      b = grid_point(m.point(m.to_vertex_handle(hn)));
      if (orient2d(p1, a, b) <= 0) return kIllegal;  // flip or degenerate
      e = std::max(e, err.triangle(p1, a, b));
      if (e > max_error_) return kIllegal;
    }
    return e;
  }

 private:
  static constexpr double kNoLimit = 1e300;
  template <class Point>
  static GridPoint grid_point(const Point& p) {
    return GridPoint{int(std::lround(double(p[0]))), int(std::lround(double(p[1])))};
  }

  const Heightfield* hf_ = nullptr;
  ErrorMetric metric_ = ErrorMetric::Continuous;
  double max_error_ = kNoLimit;
};

}  // namespace terralod::pm
