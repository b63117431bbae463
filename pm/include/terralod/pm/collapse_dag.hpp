// Dependency DAG of a progressive mesh's collapses, with the faces each collapse removes and
// creates and nested bounding volumes: the static data of view-dependent selective refinement.
//
// Usage:
//   terralod::pm::ProgressiveMesh pm = terralod::pm::ProgressiveMesh::build(hf);
//   terralod::pm::CollapseDag dag(pm);                     // O(collapses); copies what it needs
//   for (std::uint32_t p : dag.preds(c)) { /* c can only be performed after p */ }
//   for (std::uint32_t f : dag.created_faces(c)) { auto [a, b, d] = dag.face(f); }
//
// Model (Hoppe 1997, seeds/view-dependent-pm-dynamic-loading.txt section 3, with the faces of
// De Floriani and Puppo's multi-triangulation). Replaying the PM's half-edge collapses c_0,
// c_1, ... (u -> w) once, in build order, on an indexed face structure gives every face a
// unique id: the full-resolution faces keep their ProgressiveMesh::full_face number, and each
// collapse c removes the faces of u's star at that moment and creates one new face for each
// of them that does not contain w (u replaced by w, same winding). A face is created by at
// most one collapse (its creator; none for full-resolution faces) and removed by at most one
// (its remover; none for base-mesh faces). Collapse c depends on collapse p (p is a
// predecessor of c) when p created a face that c removes.
//
// Why this DAG is the right legality rule. Let S be any set of collapses closed under
// predecessors (c in S => every predecessor of c in S), and F(S) the full-resolution faces
// plus the faces created by S, minus the faces removed by S. Then:
//   (1) F(S) is the mesh obtained by performing the collapses of S in build order: when c's
//       turn comes, every face c removed during the build is present (its creator is in S,
//       and its only remover is c), so c removes exactly the star it had during the build and
//       puts back exactly the faces it created then.
//   (2) F(S) is a valid plan-view triangulation of the domain: each such step replaces the
//       faces of a star, which tile a polygon with u inside (or on the grid border), by a fan
//       from w that tiles the same polygon with the same boundary edges - the build checked
//       that none of them flips or degenerates - so coverage and conformity are kept.
//   (3) Every face of F(S) existed during the build and was measured by the collapse that
//       created it: its error at the original samples it covers is at most its creator's
//       error (0 for a full-resolution face). Faces that mix levels never seen by the build
//       cannot occur. With ErrorMetric::Continuous the builder measures a collapse's new edges
//       only; an older edge of a created face was measured by the collapse that made it, a
//       transitive predecessor, so the face's continuous error is at most its creator's
//       saturated error (tests check both over every created face).
//   (4) Performing a collapse c not in S whose predecessors are in S (an ecol), or undoing a
//       collapse c in S none of whose successors is in S (a vsplit), keeps S closed and
//       changes F(S) by exactly c's removed/created faces, in any order.
//
// Bounding volumes (for view culling and the screen-space test): volume(c) contains, for
// every face c creates, the face extruded vertically by +-error(c) (every vertical error
// segment of the face at a sample lies inside), and the volume of every predecessor of c.
// Boxes are also clipped to the heightfield's height range, which holds every such segment
// (its ends are a sample and a point of the mesh, whose corners are samples). So volumes and
// saturated errors (max of c's error and its predecessors') never shrink along the DAG,
// which makes the screen-space test monotone (see selective_refinement.hpp).
//
// Contract:
//   - Collapse indices are ProgressiveMesh::collapses() indices (build order); the vertex
//     hierarchy's vsplit k is collapse collapse_count() - 1 - k.
//   - Samples are row * width + col; positions are world metres (hf.transform, z = height).
//   - Throws std::invalid_argument when the collapses do not replay (a collapse whose u and w
//     are not joined by an edge, or one that would flip a face): the PM is corrupt.
//   - Memory (measured): about 240 bytes per full-resolution vertex - per face id (about 5.4
//     per vertex) its corners, creator and remover (20 bytes); per collapse its removed-face
//     list, 2.4 DAG edges each way, a box (32 bytes: PackedBox) or sphere (32) and its
//     saturated error - plus the copied heightfield (8 bytes per sample). Building peaks at
//     about 80 more bytes per vertex (per-sample face lists). Build time about 2.5 s per
//     million vertices.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/progressive_mesh.hpp"
#include "terralod/pm/view.hpp"

namespace terralod::pm {

/// Shape of the nested bounding volumes.
enum class VolumeKind : std::uint8_t {
  Box = 0,     ///< axis-aligned boxes: tight for flat terrain regions (the default)
  Sphere = 1,  ///< spheres, as in Hoppe 1997 and the PM paper's Fig. 4
};

struct DagOptions {
  VolumeKind volume = VolumeKind::Box;
  /// The first `skip` collapses of the PM are performed before the DAG starts: its finest mesh
  /// (its "full-resolution" faces, the leaves) is the PM's mesh after them, and its collapses
  /// are the rest. A far block needs only the coarse end of its PM, and this DAG holds only
  /// that: its memory follows the collapses it keeps, plus 20 bytes a sample (heights, mask,
  /// removed_by). Every face of the leaves keeps, as its error, the saturated error of the
  /// skipped collapse that made it (leaf_error), so the error bound of every mesh of the DAG
  /// still holds; floor_error() is the largest.
  std::size_t skip = 0;
};

class CollapseDag {
 public:
  static constexpr std::uint32_t kNone = 0xffffffffu;

  /// Replays `pm` once; the PM need not outlive the DAG.
  explicit CollapseDag(const ProgressiveMesh& pm, const DagOptions& options = {});
  /// The largest DagOptions::skip whose leaves are within floor_m of the samples: the length
  /// of the PM's prefix whose errors are all <= floor_m (0 when floor_m is below the first).
  static std::size_t skip_for_floor(const ProgressiveMesh& pm, double floor_m);

  const Heightfield& heightfield() const { return hf_; }
  VolumeKind volume_kind() const { return kind_; }

  // --- Collapses -----------------------------------------------------------------------------
  /// The DAG's collapses: the PM's collapses from skipped() on (DAG collapse c is PM collapse
  /// skipped() + c).
  std::size_t collapse_count() const { return collapses_.size(); }
  std::size_t skipped() const { return skipped_; }
  const Collapse& collapse(std::uint32_t c) const { return collapses_[c]; }
  /// max(error(c), saturated_error(p) for every predecessor p), metres.
  double saturated_error(std::uint32_t c) const { return saturated_[c]; }
  std::span<const std::uint32_t> preds(std::uint32_t c) const { return span(pred_off_, preds_, c); }
  std::span<const std::uint32_t> succs(std::uint32_t c) const { return span(succ_off_, succs_, c); }
  /// c's box as one 32-byte record: the box in floats relative to the heightfield's origin
  /// (x0, y0, 0), rounded outwards so that origin + float (in doubles) contains the exact box,
  /// and the saturated error rounded up to a float. SelectiveRefinement tests these records
  /// as they are, so a resident block holds its boxes once (32 bytes a collapse instead of 48
  /// here and 32 more in every refinement). Rounding outwards is monotonic: the boxes still
  /// nest along the DAG.
  struct PackedBox {
    float lo[3], hi[3];
    float error, unused;
  };
  /// The records of all collapses; empty when volume_kind() is Sphere.
  const std::vector<PackedBox>& packed_boxes() const { return boxes_; }
  /// The volume of c (volume_kind() decides which one is stored): box() is packed_boxes()[c]
  /// back in world metres.
  Box box(std::uint32_t c) const {
    const PackedBox& b = boxes_[c];
    const double ox = hf_.transform.x0, oy = hf_.transform.y0;
    return {{ox + double(b.lo[0]), oy + double(b.lo[1]), double(b.lo[2])},
            {ox + double(b.hi[0]), oy + double(b.hi[1]), double(b.hi[2])}};
  }
  const Sphere& sphere(std::uint32_t c) const { return spheres_[c]; }

  // --- Faces ---------------------------------------------------------------------------------
  /// Number of face ids (full-resolution slots plus created faces); some slots are unused.
  std::size_t face_id_count() const { return faces_.size(); }
  /// Corners (samples) of face f, CCW in (col,row); corners[0] == kNone for an unused slot.
  const std::array<std::uint32_t, 3>& face(std::uint32_t f) const { return faces_[f]; }
  std::uint32_t creator(std::uint32_t f) const { return creator_[f]; }  ///< kNone: a leaf
  /// Error of a leaf face (creator kNone): 0 at full resolution, else the saturated error of
  /// the skipped collapse that made it (DagOptions::skip), rounded up to a float.
  double leaf_error(std::uint32_t f) const { return leaf_error_.empty() ? 0.0 : double(leaf_error_[f]); }
  /// Error of face f as drawn: its creator's error, or its leaf error.
  double face_error(std::uint32_t f) const {
    return creator_[f] == kNone ? leaf_error(f) : collapses_[creator_[f]].error;
  }
  /// Saturated error of face f: its creator's saturated error, or its leaf error.
  double face_saturated_error(std::uint32_t f) const {
    return creator_[f] == kNone ? leaf_error(f) : saturated_[creator_[f]];
  }
  /// The largest leaf error: no mesh of the DAG is closer to the samples than this allows.
  double floor_error() const { return floor_error_; }
  std::uint32_t remover(std::uint32_t f) const { return remover_[f]; }  ///< kNone: in the base mesh
  /// Faces of u's star that c removes (in the build: the faces it deletes and changes).
  std::span<const std::uint32_t> removed_faces(std::uint32_t c) const {
    return span(removed_off_, removed_, c);
  }
  /// Ids of the faces c creates: [first, last).
  std::pair<std::uint32_t, std::uint32_t> created_faces(std::uint32_t c) const {
    return {created_base_ + created_off_[c], created_base_ + created_off_[c + 1]};
  }
  /// The leaves, ascending: the full-resolution faces of the domain (ids < full_face_slots) when
  /// nothing is skipped, else the faces of the mesh after the skipped collapses (ids 0 .. L-1).
  const std::vector<std::uint32_t>& full_faces() const { return full_faces_; }

  // --- Vertices ------------------------------------------------------------------------------
  /// Vertices of the leaves (all the samples' vertices when nothing is skipped).
  std::size_t full_vertex_count() const { return full_vertex_count_; }
  /// Collapse that removes sample s, or kNone for base-mesh vertices and samples that are not
  /// vertices of the leaves.
  std::uint32_t removed_by(std::uint32_t s) const { return removed_by_[s]; }
  /// World position of sample s: (x, y) = transform.to_world(col, row), z = its height.
  Vec3 position(std::uint32_t s) const;
  /// World position of a point (col, row) in index space at height z (same arithmetic).
  Vec3 position(double col, double row, double z) const;

  /// Bytes held by this object.
  std::size_t memory_bytes() const;

 private:
  static std::span<const std::uint32_t> span(const std::vector<std::uint32_t>& off,
                                             const std::vector<std::uint32_t>& v, std::uint32_t c) {
    return {v.data() + off[c], v.data() + off[c + 1]};
  }
  Heightfield hf_;
  VolumeKind kind_ = VolumeKind::Box;
  std::vector<Collapse> collapses_;
  std::vector<double> saturated_;
  std::vector<std::uint32_t> pred_off_, preds_, succ_off_, succs_;
  void set_box(std::uint32_t c, const Box& b);
  std::vector<PackedBox> boxes_;
  std::vector<Sphere> spheres_;
  std::vector<std::array<std::uint32_t, 3>> faces_;
  std::vector<std::uint32_t> creator_, remover_;
  std::vector<std::uint32_t> removed_off_, removed_;
  std::vector<std::uint32_t> created_off_;
  std::uint32_t created_base_ = 0;
  std::vector<std::uint32_t> full_faces_;
  std::vector<std::uint32_t> removed_by_;
  std::size_t full_vertex_count_ = 0;
  std::size_t skipped_ = 0;
  std::vector<float> leaf_error_;  // by leaf face, rounded up; empty when every leaf error is 0
  double floor_error_ = 0;
};

}  // namespace terralod::pm
