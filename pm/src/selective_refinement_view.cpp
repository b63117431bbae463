// SelectiveRefinement's view test and screen-space bound: which collapses a view accepts (per
// collapse and, streaming, per list), and the bound of the active faces that update() reports.
//
// Paper: seeds/view-dependent-pm-dynamic-loading.txt, section 3 (screen-space error); the
// guarantee argument is in selective_refinement.hpp and the projection bound in view.cpp.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "selective_refinement_frame.hpp"
#include "terralod/pm/selective_refinement.hpp"

namespace terralod::pm {

namespace {
constexpr std::uint32_t kNone = CollapseDag::kNone;
}  // namespace

// 0: not ok (refine); 1: ok by the error test; 2: ok because volume(c) is outside the frustum.
int SelectiveRefinement::classify(Frame& fr, std::uint32_t c) const {
  ++fr.evaluated;
  if (const std::vector<Packed>& packed = dag_->packed_boxes(); !packed.empty())
    return classify_box(fr, packed[c]);  // boxes: one 32-byte record per test
  const double E = dag_->saturated_error(c);
  if (E == 0.0) return 1;
  const Sphere& s = dag_->sphere(c);
  if (E * fr.kf <= std::max(fr.view->min_depth(s), fr.near)) return 1;
  return fr.cull->outside(s) ? 2 : 0;
}

int SelectiveRefinement::classify_box(const Frame& fr, const Packed& t) {
  if (t.error == 0.0f) return 1;
  const double cx = 0.5 * (double(t.lo[0]) + t.hi[0]), hx = 0.5 * (double(t.hi[0]) - t.lo[0]);
  const double cy = 0.5 * (double(t.lo[1]) + t.hi[1]), hy = 0.5 * (double(t.hi[1]) - t.lo[1]);
  const double cz = 0.5 * (double(t.lo[2]) + t.hi[2]), hz = 0.5 * (double(t.hi[2]) - t.lo[2]);
  const double zmin = fr.pd0 + fr.pf[0] * cx + fr.pf[1] * cy + fr.pf[2] * cz -
                      (std::abs(fr.pf[0]) * hx + std::abs(fr.pf[1]) * hy + std::abs(fr.pf[2]) * hz);
  if (double(t.error) * fr.kf <= std::max(zmin, fr.near)) return 1;
  for (int k = 0; k < 6; ++k) {
    const double* q = fr.pl[k];
    if (q[0] * cx + q[1] * cy + q[2] * cz + q[3] + std::abs(q[0]) * hx + std::abs(q[1]) * hy +
            std::abs(q[2]) * hz <
        0.0)
      return 2;
  }
  return 0;
}

// Bound of one active face (its record: corners, their heights, its creator's error): the
// error over the smallest depth of its prism (the face extruded by +-error vertically); 0 for
// full-resolution faces and for faces whose prism is outside the view frustum (all their
// error segments are). Depth is affine in (col, row, z), so the corners are read as sample
// indices and heights only; records are contiguous, so this pass streams through memory.
double SelectiveRefinement::face_bound_px(const Frame& fr, const FaceRec& r) const {
  const double e = r.error;
  if (e == 0.0) return 0.0;
  // The prism is clipped to the heights of the samples, which hold every error segment (both
  // ends are heights of samples or of the mesh between samples), as the volumes are.
  double zmin = 1e300, zmax = -1e300;
  double col[3], row[3], lo[3], hi[3];
  for (int k = 0; k < 3; ++k) {
    // row = s / W through a double reciprocal: exact, since s < 2^32 keeps the rounding error of
    // (s + 0.5) / W far below its distance 0.5 / W to the nearest integer.
    const std::uint32_t s = r.s[k], rw = std::uint32_t((double(s) + 0.5) * fr.inv_w);
    col[k] = double(s - rw * fr.w), row[k] = double(rw);
    lo[k] = std::max(r.z[k] - e, zlo_), hi[k] = std::min(r.z[k] + e, zhi_);
    const double d = fr.d0 + fr.dc * col[k] + fr.dr * row[k];
    zmin = std::min(zmin, d + std::min(fr.dz * lo[k], fr.dz * hi[k]));
    zmax = std::max(zmax, d + std::max(fr.dz * lo[k], fr.dz * hi[k]));
  }
  if (zmax < fr.near) return 0.0;  // in front of the near plane
  const double b = e * fr.kvf / std::max(zmin, fr.near);
  if (!(b > fr.floor)) return b;  // cannot raise the maximum: skip the plane tests
  const GridTransform& t = dag_->heightfield().transform;
  for (const Plane& pl : fr.view->planes()) {
    double top = -1e300;
    for (int k = 0; k < 3; ++k) {
      const double x = t.x0 + col[k] * t.xc + row[k] * t.xr, y = t.y0 + col[k] * t.yc + row[k] * t.yr;
      top = std::max(top, pl.n.x * x + pl.n.y * y + std::max(pl.n.z * lo[k], pl.n.z * hi[k]) + pl.d);
    }
    if (top < 0.0) return 0.0;  // the prism is outside this plane
  }
  return b;
}

// The bound pass of update(): the same maximum as applying face_bound_px to every active face
// (bound_px(view), the reference), computed exactly only for the faces that could raise it. For each
// face, the float box of its clipped prism (fbox_, rounded outwards) has a smallest depth zl <=
// the prism's, so ub = ferr * K vf / max(zl, near) >= face_bound_px (ferr >= error; a face
// outside the view only gets 0). A face with ub <= the running maximum cannot raise it, and
// the original pass would have counted it with b <= the maximum (or 0): it is skipped. The
// depths are affine in the box corners, so the test is three multiply-adds per face on
// contiguous arrays (16 bytes per face) instead of 48 bytes and a dozen operations; a relative
// slack of 1e-9 covers the rounding of both computations. The face that attained the last
// frame's bound is evaluated first, so the running maximum starts near its final value.
// bound_m, the largest error of the faces whose float prism box is not outside the view
// frustum, is found in the same pass: only faces with a larger (rounded-up) error are tested.
double SelectiveRefinement::filtered_bound_px(Frame& fr, double& bound_m) {
  double bound = 0.0;
  bound_m = 0.0;
  fr.floor = 0.0;
  std::size_t best = kNone;
  auto exact = [&](std::size_t i) {
    const double b = face_bound_px(fr, face_rec_[i]);
    if (b > bound) bound = b, best = i, fr.floor = b;
  };
  const std::size_t n = active_.size();
  const std::size_t seed = bound_face_ == kNone ? kNone : face_pos_[bound_face_];
  if (seed != kNone) exact(seed);
  const float* X = fbox_[fr.pf[0] >= 0.0 ? 0 : 1].data();
  const float* Y = fbox_[fr.pf[1] >= 0.0 ? 2 : 3].data();
  const float* Z = fbox_[fr.pf[2] >= 0.0 ? 4 : 5].data();
  const float* E = ferr_.data();
  const double a0 = fr.pf[0], a1 = fr.pf[1], a2 = fr.pf[2], near = fr.near;
  const GridTransform& g = dag_->heightfield().transform;
  const double slack = 1e-9 * (1.0 + std::abs(fr.pd0) + std::abs(g.x0) + std::abs(g.y0) + coord_scale_);
  const double z0 = fr.pd0 - slack;
  const double k1 = fr.kvf * (1.0 + 1e-9);
  // A candidate whose box is behind the near plane or outside a plane of the view frustum has
  // a prism that is too (face_bound_px returns 0 for it): it is skipped before the exact test.
  // The planes here are the view's (not the widened cull frustum's), relative to (x0, y0, 0).
  double pl[6][4];
  for (int k = 0; k < 6; ++k) {
    const Plane& q = fr.view->planes()[std::size_t(k)];
    pl[k][0] = q.n.x, pl[k][1] = q.n.y, pl[k][2] = q.n.z;
    pl[k][3] = q.distance(Vec3{g.x0, g.y0, 0.0}) + slack;
  }
  auto box_out = [&](std::size_t i) {
    const double lo[3] = {fbox_[0][i], fbox_[2][i], fbox_[4][i]},
                 hi[3] = {fbox_[1][i], fbox_[3][i], fbox_[5][i]};
    double zmax = fr.pd0 + slack;
    for (int a = 0; a < 3; ++a) zmax += std::max(fr.pf[a] * lo[a], fr.pf[a] * hi[a]);
    if (zmax < near) return true;
    for (const auto& q : pl) {
      double top = q[3];
      for (int a = 0; a < 3; ++a) top += std::max(q[a] * lo[a], q[a] * hi[a]);
      if (top < 0.0) return true;
    }
    return false;
  };
  // Chunks: a first loop flags the faces that pass either test against the maxima at the start
  // of the chunk; the flagged ones are tested again against the running maxima.
  constexpr std::size_t kChunk = 64;
  bool flag[kChunk];
  for (std::size_t i0 = 0; i0 < n; i0 += kChunk) {
    const std::size_t m = std::min(kChunk, n - i0);
    const double thr = fr.floor, thr_m = bound_m;
    for (std::size_t j = 0; j < m; ++j) {
      const std::size_t i = i0 + j;
      const double zl = z0 + a0 * double(X[i]) + a1 * double(Y[i]) + a2 * double(Z[i]);
      flag[j] = (double(E[i]) * k1 > thr * std::max(zl, near)) | (double(E[i]) > thr_m);
    }
    for (std::size_t j = 0; j < m; ++j) {
      if (!flag[j]) continue;
      const std::size_t i = i0 + j;
      const double zl = z0 + a0 * double(X[i]) + a1 * double(Y[i]) + a2 * double(Z[i]);
      const bool by_bound = i != seed && double(E[i]) * k1 > fr.floor * std::max(zl, near);
      const bool by_error = double(E[i]) > bound_m;
      if ((!by_bound && !by_error) || box_out(i)) continue;
      if (by_error) bound_m = std::max(bound_m, face_rec_[i].error);
      if (by_bound) exact(i);
    }
  }
  bound_face_ = best == kNone ? kNone : active_[best];
  return bound;
}

// True when volume(c) is outside the view frustum itself (not the widened cull frustum).
bool SelectiveRefinement::outside_view(const Frame& fr, std::uint32_t c) const {
  return dag_->volume_kind() == VolumeKind::Box ? fr.view->outside(dag_->box(c))
                                                : fr.view->outside(dag_->sphere(c));
}

double SelectiveRefinement::bound_px(const View& view) const {
  Frame fr(view, dag_->heightfield(), tau_);
  for (const FaceRec& r : face_rec_) fr.floor = std::max(fr.floor, face_bound_px(fr, r));
  return fr.floor;
}

// Loads the work stack with the items of `set`, in list order, each with its verdict when it
// was tested here (-1: untested). With boxes every item is tested now and only those whose
// verdict is wanted are loaded (want_ok: the ok ones, verdicts 1 and 2; else the not-ok ones):
// the test is a pure function of the collapse and the view, so this skips exactly the items the
// loop would have tested and dropped.
void SelectiveRefinement::prefilter(Frame& fr, const IndexSet& set, bool want_ok) {
  work_.clear(), work_verdict_.clear();
  if (set.recs.empty()) {
    work_ = set.items;
    work_verdict_.assign(work_.size(), -1);
    return;
  }
  const std::size_t n = set.items.size();
  fr.evaluated += n;
  for (std::size_t i = 0; i < n; ++i) {
    const int v = classify_box(fr, set.recs[i]);
    if ((v != 0) == want_ok) work_.push_back(set.items[i]), work_verdict_.push_back(std::int8_t(v));
  }
}

}  // namespace terralod::pm
