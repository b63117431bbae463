// View-dependent selective refinement of a progressive mesh: a vertex front (a closed set of
// performed collapses) updated incrementally frame to frame, with a guaranteed screen-space
// error, a triangle-budget mode, and runtime geomorphs.
//
// Usage:
//   terralod::pm::ProgressiveMesh pm = terralod::pm::ProgressiveMesh::build(hf);
//   terralod::pm::CollapseDag dag(pm);                        // must outlive the selection
//   terralod::pm::RefinementOptions opt;
//   opt.tolerance_px = 1.0;                                   // tau, pixels
//   opt.morph_seconds = 0.5;                                  // geomorphs; 0 = pop
//   terralod::pm::SelectiveRefinement sel(dag, opt);          // starts at the base mesh
//   for (double t = 0;; t += 1.0 / 60) {
//     const terralod::pm::FrameStats& s = sel.update(terralod::pm::View(camera_at(t)), t);
//     // s.bound_px <= s.tolerance_px: every in-frustum triangle is within the bound
//     terralod::pm::RenderMesh m = sel.render_mesh();        // displayed positions
//   }
//
// Paper: seeds/view-dependent-pm-dynamic-loading.txt, section 3 (vertex front moved up and
// down the hierarchy by vsplit/ecol, screen-space error, bounding spheres, geomorphs); Hoppe
// 1997/1998 (active vertex list, frame coherence, triangle budget by regulating tau).
//
// The selection is the set S of performed collapses, always closed under the predecessors of
// CollapseDag, so the active mesh F(S) is a valid plan-view triangulation whose every face has
// L-infinity error <= the error of the collapse that created it (collapse_dag.hpp). A vsplit
// undoes a collapse c in S (first undoing, recursively, every collapse of S that depends on
// c); an ecol performs a collapse not in S (first performing, recursively, every collapse it
// depends on). The "active vertex front" is kept as two lists: tops (collapses of S with no
// successor in S: the vsplits legal now) and the frontier (collapses outside S whose
// predecessors are all in S: the ecols legal now).
//
// The guarantee. For a view and tolerance tau (pixels), call collapse c acceptable, ok(c), when
//     volume(c) lies outside the frustum,  or  E(c) * K * vf / max(zmin(c), near) <= tau,
// where E(c) is c's saturated error, zmin(c) the smallest depth of volume(c), K and vf the
// View's focal_px() and vertical_factor(). (With cull_margin > 1, "the frustum" here is the
// widened one, which contains the view's; nothing below changes.)
//   (a) If c is in S and ok(c), every face c created meets tau: such a face f is within
//       error(c) <= E(c) of the full-resolution surface at every sample it covers
//       (collapse_dag.hpp, point 3); each vertical segment between f and such a sample lies
//       in volume(c), so the part of it inside the frustum projects to at most
//       E(c) K vf / max(zmin, near) <= tau pixels (view.cpp derives this), or to nothing when
//       volume(c) is outside. Full-resolution faces have no error.
//   (b) ok is monotone along the DAG: volume(p) lies inside volume(c) and E(p) <= E(c) for
//       every predecessor p, so ok(c) implies ok(p). Hence S* = {c : ok(c)} is closed.
//   (c) update() computes exactly S*: it undoes every top that is not ok (if some c in S is not
//       ok, a top above it is not ok, by (b)), then performs every frontier collapse that is ok
//       (a minimal ok collapse outside S is on the frontier). So every collapse of S is ok and
//       (a) applies to every active face. The result does not depend on the previous frame;
//       only the work does.
// FrameStats::bound_px reports the max over the active faces whose prism (the face extruded
// by +-error(creator) vertically, clipped to the samples' height range) is not outside the
// view frustum of error(creator) * K * vf / max(zmin(prism), near): a tighter number, <= tau
// by the same argument (the prism lies in volume(creator)). update() finds that maximum without
// evaluating every face: a float box of each prism gives an upper bound of the face's number
// in three multiply-adds, and only faces whose upper bound exceeds the running maximum (and
// whose box is not outside the view) are evaluated exactly; the result is bit for bit the one
// of the full pass, bound_px(view) (tests/pm/test_selective_refinement_bound.cpp). Likewise
// the tops and the frontier keep their collapses' packed boxes beside them, so the per-frame
// tests stream through memory. Volumes are boxes by default; VolumeKind::Sphere
// gives the PM paper's spheres (measured: 7.7% more triangles for the same tau,
// tests/pm/test_selective_refinement.cpp).
//
// Triangle budget (RefinementOptions::target_triangles > 0): before each update tau is
// multiplied by (previous triangles / target)^budget_gain, clamped to a factor in [1/2, 2]
// and to [min_tolerance_px, max_tolerance_px]; FrameStats::tolerance_px reports the tau
// used and bound_px <= it holds as above.
//
// Geomorphs (morph_seconds > 0). Refinement is never delayed: S is S* after every update, and
// the guarantee holds for the logical mesh (mesh(), FrameStats); only the displayed positions
// (render_mesh()) lag behind, so that nothing pops. Coarsening waits for its morph. Two modes:
//   MorphMode::Full (the default; Hoppe's geomorph, made fold-free). A vertex u that a vsplit
//   of c (u -> w) brings back first rides on w (at w's displayed position: u's new faces are
//   degenerate or copies of w's, so the surface does not change), then slides in plan and
//   height to its own sample over morph_seconds. It leaves w only when (1) no vertex of a
//   collapse depending on c still rides (coarser vertices go first), and (2) no face around
//   it or around the vertices riding on it would fold over before every planned slide ends:
//   each vertex's plan-view track is piecewise linear in time, so a face's signed area is
//   piecewise quadratic, and its minimum is checked. With (1) the displayed mesh is always
//   the geometry of F(S u V) (V: the collapses whose vertex rides), a valid triangulation, and
//   every slide ends in one; with (2) no face folds in between. Every sample's height then
//   changes continuously.
//   An ecol of c first slides u to w (it starts only when no corner of the faces c creates
//   moves, and no neighbour can start while it runs); c is performed when u arrives (the
//   faces that vanish are degenerate then). Meanwhile c is pending: outside S, so what
//   depends on it waits; it is cancelled (u slides back) when c stops being ok or leaves the
//   frontier. A vertex still riding when its ecol comes is collapsed at once (it is already
//   where the ecol puts it).
//   MorphMode::Vertical (heights only; plan positions stay on the grid, so nothing can fold).
//   A new vertex starts at the height that the surface displayed before the update has at
//   its sample, and a coarsening vertex moves down to the coarse surface; at the vertices
//   the change per frame is then bounded by the morph time, but between them a vsplit still
//   changes the surface at once, because the new triangles cross the old ones' creases
//   (measured: as large as the pops without geomorphs; tests/pm/test_geomorph.cpp).
//   In both modes, changes whose region is outside the view frustum are done at once where
//   that keeps the invariants (Vertical vsplits, ecols), and a guard band (cull_margin > 1)
//   refines terrain before it turns into view. Once the camera stops, the morphs end and the
//   selection and positions are bit-identical to those of a selection without geomorphs.
//
// Contract: view parameters come validated by View; time_s passed to update() must not
// decrease (std::invalid_argument otherwise); options are checked on construction and in
// set_options() (std::invalid_argument); changing the morph settings ends running morphs.
// Memory: about 18 bytes per collapse (state, list positions; its box and error are the DAG's),
// 32 more per top and per frontier collapse (its box beside the list), 4 per face id, 8 per
// sample, 76 per active triangle (48 for the exact bound, 28 for its float box and error), 80
// per morphing vertex, and with Full geomorphs 32 bytes per sample (its first seven faces) plus
// a list for a vertex of more faces.
// Time: per update O(tops + frontier + changes) for the selection plus one streaming pass
// over the active triangles (16 bytes each) for the reported bound; measured at 1280 x 720,
// tau = 1 px on a 100 m/s flight: 0.23 ms median (0.10 ms of it the bound; 1.28 and 0.56
// before the streaming passes) for 44k triangles of a 513 x 513 terrain (one core, Release,
// loaded machine; DISABLED_Flight513Generated in tests/pm/test_selective_refinement.cpp).
// Each vsplit/ecol costs about 1.5x what it did before those passes (a face also moves its
// float box, a list item its record): a cold start of the 25 N44W072 blocks at tau 0.5 px
// (14k vsplits) takes about 14 ms instead of 9.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include "terralod/pm/collapse_dag.hpp"
#include "terralod/pm/progressive_mesh.hpp"
#include "terralod/pm/view.hpp"

namespace terralod::pm {

/// How geomorphing vertices move (see the header comment).
enum class MorphMode : std::uint8_t {
  Vertical = 0,  ///< only heights move: cannot fold, but pops between vertices at a vsplit
  Full = 1,      ///< a new vertex rides on its parent, then slides: no pop, scheduled not to fold
};

struct RefinementOptions {
  double tolerance_px = 1.0;  ///< tau, pixels, > 0 (the start value in budget mode)
  /// Budget mode when > 0: tau is regulated frame to frame to hold this many triangles.
  std::size_t target_triangles = 0;
  double budget_gain = 1.0;        ///< exponent of the regulation, in (0, 2]
  double min_tolerance_px = 0.01;  ///< budget-mode range of tau, 0 < min <= max
  double max_tolerance_px = 1.0e4;
  /// Geomorph duration, seconds, >= 0; 0 turns geomorphs off (vertices pop).
  double morph_seconds = 0.0;
  MorphMode morph_mode = MorphMode::Full;
  /// Guard band, in [1, 10]: collapses are culled against the view frustum widened so that the
  /// tangents of its half-angles are this many times the view's (near and far unchanged).
  /// 1 culls exactly; more refines a band around the view so that terrain turning into view
  /// is already refined (and morphs less) when it appears. The guarantee holds for any value.
  double cull_margin = 1.0;
};

/// What one update did and guarantees.
struct FrameStats {
  std::size_t active_vertices = 0, triangles = 0;
  std::size_t vsplits = 0, ecols = 0;  ///< operations on the selection in this update
  std::size_t evaluated = 0;           ///< view tests of collapses
  std::size_t morphing = 0;            ///< vertices moving after this update
  std::size_t pending_ecols = 0;       ///< of those, moving towards a collapse
  double tolerance_px = 0.0;           ///< tau used (regulated in budget mode)
  double bound_px = 0.0;  ///< guaranteed screen-space error of every in-frustum triangle, <= tolerance_px
  /// Largest error at the samples (metres) of an active triangle that may be in view (the box
  /// of its prism, the triangle extruded by +-its error, is not outside the view frustum); 0
  /// when none is. The metric bound of what is seen.
  double bound_m = 0.0;
  double update_ms = 0.0;  ///< wall time of update(), including the bound
  double bound_ms = 0.0;   ///< of which computing bound_px and bound_m (a pass over the faces)
};

/// Positions for drawing: the active vertices, where they are displayed now, and triangles.
struct RenderMesh {
  std::vector<std::uint32_t> samples;                   ///< sample of each vertex
  std::vector<Vec3> positions;                          ///< displayed world position, metres
  std::vector<std::array<std::uint32_t, 3>> triangles;  ///< indices; CCW in (col,row) at rest
  /// Per triangle: the error of the collapse that created it (0 for a full-resolution face),
  /// metres: the face is within it of the full-resolution surface (collapse_dag.hpp, point 3),
  /// and FrameStats::bound_px bounds it with this error.
  std::vector<double> errors;
};

class SelectiveRefinement {
 public:
  SelectiveRefinement(const CollapseDag& dag, const RefinementOptions& options = {});

  const CollapseDag& dag() const { return *dag_; }
  const RefinementOptions& options() const { return opt_; }
  void set_options(const RefinementOptions& options);

  /// Moves the front to S* for `view` (see above); time_s drives geomorphs (seconds).
  const FrameStats& update(const View& view, double time_s = 0.0);
  const FrameStats& stats() const { return stats_; }

  /// Forced operations (legal in any state): vsplit undoes c and, first, every performed
  /// collapse that depends on it; ecol performs c and, first, every collapse it depends on.
  /// Both return the number of collapses undone/performed (0 if c already was in that state)
  /// and act at once: running geomorphs end first (vertices jump to their samples).
  std::size_t vsplit(std::uint32_t c);
  std::size_t ecol(std::uint32_t c);

  bool performed(std::uint32_t c) const { return in_s_[c] != 0; }
  std::size_t performed_count() const { return performed_; }
  std::size_t active_vertex_count() const { return dag_->full_vertex_count() - performed_; }
  std::size_t triangle_count() const { return active_.size(); }
  /// Active face ids (CollapseDag::face), in no particular order.
  const std::vector<std::uint32_t>& active_faces() const { return active_; }
  /// Vsplits legal now (tops) and ecols legal now (frontier).
  const std::vector<std::uint32_t>& tops() const { return tops_.items; }
  const std::vector<std::uint32_t>& frontier() const { return frontier_.items; }

  /// The logical active mesh: samples, triangles (ordered by face id), true heights;
  /// error_bound = the largest saturated error of its faces' creators: its L-infinity error
  /// bound in metres, for either metric (collapse_dag.hpp, point 3).
  TriangleMesh mesh() const;
  /// The displayed mesh at the time of the last update (geomorph positions), triangles
  /// ordered by face id, vertices in order of first use.
  RenderMesh render_mesh() const;
  /// The same mesh into `out`, reusing its storage, with the triangles in no particular order
  /// (the active list's): no sort, no allocation once `out` has grown. For per-frame use.
  void render_mesh_into(RenderMesh& out) const;
  /// True while some vertex is moving.
  bool morphing() const { return !morphs_.empty(); }

  /// One running geomorph, as planned at the last update: the vertex at `sample` moves on a
  /// straight line from `from` (at time t0) to `to` (at t1), positions (col, row, z); a vertex
  /// riding on `anchor` (a new vertex waiting to slide off its parent) is displayed wherever
  /// the anchor is and has t1 = infinity. t1 - t0 never exceeds morph_seconds, so no vertex
  /// moves faster than its jump divided by the morph time.
  struct MorphState {
    std::uint32_t sample = 0;
    std::array<double, 3> from{}, to{};
    double t0 = 0, t1 = 0;
    std::uint32_t anchor = CollapseDag::kNone;  ///< kNone when not riding
    bool pending_ecol = false;                  ///< moving towards a collapse
  };
  /// The running geomorphs (for tests, statistics and debugging views).
  std::vector<MorphState> morph_states() const;

  /// Screen-space bound of the current faces for a view, as in FrameStats::bound_px, by the
  /// plain pass over every face (update() gets the same number faster; this is its reference).
  double bound_px(const View& view) const;

  /// Heap bytes this refinement holds now (its arrays' capacities; the DAG's are
  /// CollapseDag::memory_bytes). It grows as the mesh is refined and morphs start.
  std::size_t memory_bytes() const;
  /// What memory_bytes() comes to for a refinement of `dag` with `options` at full resolution,
  /// its largest selection, with no geomorph running: what a caller reserves for one. It can
  /// be passed while geomorphs run (80 bytes a morphing vertex) and by lists that kept the
  /// capacity of a coarser selection (the tops; with Full geomorphs, the faces of a vertex
  /// beyond its seventh); test_block_memory refines blocks to full resolution against it.
  static std::size_t full_memory_bytes(const CollapseDag& dag, const RefinementOptions& options);

 private:
  using Packed = CollapseDag::PackedBox;  // box relative to (x0, y0, 0), saturated error
  // A set of collapses with O(1) insert/erase; with boxes, each item's packed test record is
  // kept beside it (recs, parallel to items), so a pass over the set streams through memory.
  struct IndexSet {
    std::vector<std::uint32_t> items, pos;
    std::vector<Packed> recs;  // empty without boxes (spheres)
    bool has(std::uint32_t c) const { return pos[c] != CollapseDag::kNone; }
    /// packed: the records of all collapses (CollapseDag::packed_boxes()), or empty.
    void insert(std::uint32_t c, const std::vector<Packed>& packed) {
      if (has(c)) return;
      pos[c] = std::uint32_t(items.size());
      items.push_back(c);
      if (!packed.empty()) recs.push_back(packed[c]);
    }
    void erase(std::uint32_t c) {
      if (!has(c)) return;
      const std::uint32_t last = items.back(), p = pos[c];
      items[p] = last;
      pos[last] = p;
      items.pop_back();
      if (!recs.empty()) {
        recs[p] = recs.back();
        recs.pop_back();
      }
      pos[c] = CollapseDag::kNone;
    }
  };
  struct Morph {
    std::uint32_t sample = 0;
    std::uint32_t collapse = CollapseDag::kNone;  ///< pending ecol, or kNone for a vsplit morph
    double t0 = 0, t1 = 0;
    std::array<double, 3> from{}, to{};  ///< (col, row, z)
    /// Full mode: the vertex it rides on (displayed at its position) until it may slide;
    /// kNone otherwise.
    std::uint32_t anchor = CollapseDag::kNone;
  };
  struct Frame;  // per-update view constants

  int classify(Frame& fr, std::uint32_t c) const;             // 0 refine, 1 ok by error, 2 ok: outside
  static int classify_box(const Frame& fr, const Packed& t);  // the same for a packed box
  void perform(std::uint32_t c);
  void undo(std::uint32_t c, bool morph);
  void add_face(std::uint32_t f);
  void remove_face(std::uint32_t f);
  std::array<double, 3> displayed(std::uint32_t sample) const;
  std::array<double, 3> rest(std::uint32_t sample) const;
  void start_morph(std::uint32_t sample, std::uint32_t collapse, const std::array<double, 3>& from,
                   const std::array<double, 3>& to, std::uint32_t anchor = CollapseDag::kNone);
  void release_anchored();
  void stop_morphs();
  void drop_rider(std::uint32_t anchor, std::uint32_t sample);
  struct Track {
    double ax, ay, bx, by, t0, t1;
    bool blocking;
  };
  Track track(std::uint32_t sample) const;
  bool can_slide(std::uint32_t sample, const std::array<double, 3>& from,
                 const std::array<double, 3>& to) const;
  void track_adjacency();
  void end_morph(std::uint32_t sample);
  double coarse_height(std::uint32_t c) const;
  void start_vsplit_morphs(const Frame& fr);
  bool outside_view(const Frame& fr, std::uint32_t c) const;
  bool corners_at_rest(std::uint32_t c) const;
  void cancel_pending(std::uint32_t c);
  struct FaceRec {  // an active face as the bound needs it, parallel to active_
    std::uint32_t s[3];
    double z[3];
    double error;  // its creator's error, metres (0: full resolution)
  };
  double face_bound_px(const Frame& fr, const FaceRec& r) const;
  void index_faces(const std::vector<std::uint32_t>& faces, std::vector<std::uint32_t>& samples,
                   std::vector<std::array<std::uint32_t, 3>>& triangles) const;
  void render_into(const std::vector<std::uint32_t>* order, RenderMesh& out) const;
  double filtered_bound_px(Frame& fr, double& bound_m);  // the bound pass of update()

  const CollapseDag* dag_;
  RefinementOptions opt_;
  double zlo_ = 0.0, zhi_ = 0.0;  // height range of the samples
  double coord_scale_ = 0.0;      // bound on |x| + |y| + |z| of the fbox_ coordinates, metres
  std::vector<std::uint8_t> in_s_;
  std::vector<std::uint32_t> preds_out_;  // predecessors not in S
  std::vector<std::uint32_t> succs_in_;   // successors in S
  IndexSet tops_, frontier_;
  std::size_t performed_ = 0;
  std::vector<std::uint32_t> active_, face_pos_;
  std::vector<FaceRec> face_rec_;
  // Also parallel to active_ (structure of arrays): the box of each face's clipped prism
  // relative to (x0, y0, 0), rounded outwards to floats, and its error rounded up. They give an
  // upper bound of face_bound_px in a few operations, so the bound pass evaluates exactly only
  // the faces that could raise the maximum.
  std::vector<float> fbox_[6];  // x lo, x hi, y lo, y hi, z lo, z hi
  std::vector<float> ferr_;
  std::uint32_t bound_face_ = CollapseDag::kNone;  // the face that attained the last bound
  bool defer_boxes_ = false;                       // true while the constructor descends to the base mesh
  void push_face_box(const FaceRec& r);
  const std::vector<Packed>& list_records() const;
  std::vector<Morph> morphs_;
  std::vector<std::uint32_t> morph_of_;  // per sample: index into morphs_, or kNone
  // Full mode only: each sample's active faces, the first kInlineFaces in place and the rest
  // in vfaces_more_ (a vertex of a coarse selection can have many); and the vertices riding on
  // each anchor, kept only while they morph. A vector per sample held 24 bytes of header and a
  // heap block beside each list: 5.3 MB of a 257 x 257 block's refinement, now 2.1 MB.
  static constexpr std::uint32_t kInlineFaces = 7;
  struct SampleFaces {
    std::uint32_t n = 0;  // faces in all
    std::array<std::uint32_t, kInlineFaces> f;
  };
  std::vector<SampleFaces> vfaces_;
  std::unordered_map<std::uint32_t, std::vector<std::uint32_t>> vfaces_more_;
  std::unordered_map<std::uint32_t, std::vector<std::uint32_t>> riders_;
  void link_face(std::uint32_t s, std::uint32_t f);
  void unlink_face(std::uint32_t s, std::uint32_t f);
  // Calls fn(f) for each active face f at sample s until it returns false; false then.
  template <class Fn>
  bool for_each_face_at(std::uint32_t s, Fn&& fn) const {
    const SampleFaces& l = vfaces_[s];
    for (std::uint32_t i = 0; i < std::min(l.n, kInlineFaces); ++i)
      if (!fn(l.f[i])) return false;
    if (l.n > kInlineFaces)
      for (std::uint32_t f : vfaces_more_.at(s))
        if (!fn(f)) return false;
    return true;
  }
  mutable std::vector<std::uint32_t> cluster_;                   // scratch of can_slide
  void prefilter(Frame& fr, const IndexSet& set, bool want_ok);  // loads work_ (see update)
  std::vector<std::uint32_t> work_;
  std::vector<std::int8_t> work_verdict_;             // parallel to work_: the item's verdict, -1 untested
  std::vector<std::uint32_t> appeared_;               // vsplits of this update waiting for their morph
  std::vector<std::uint8_t> undone_now_;              // per collapse: undone in this update's refine pass
  mutable std::vector<std::uint32_t> scratch_index_;  // per sample, for mesh output
  double time_ = 0.0;
  bool started_ = false;
  double tau_ = 1.0;
  FrameStats stats_;
};

}  // namespace terralod::pm
