// SelectiveRefinement's runtime geomorphs: the displayed positions of the vertices that move,
// the morphs of vsplits and of pending ecols, Full mode's riding and fold-free sliding.
//
// Paper: seeds/view-dependent-pm-dynamic-loading.txt, section 3 (geomorphs); the two modes
// and their guarantees are described in selective_refinement.hpp. Memory: see the header.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "terralod/pm/selective_refinement.hpp"

namespace terralod::pm {

namespace {
constexpr std::uint32_t kNone = CollapseDag::kNone;
}  // namespace

// Full geomorphs need each vertex's current faces (to keep neighbours from sliding together);
// the lists are kept only then.
void SelectiveRefinement::track_adjacency() {
  const bool need = opt_.morph_seconds > 0.0 && opt_.morph_mode == MorphMode::Full;
  if (need == !vfaces_.empty()) return;
  vfaces_ = {};
  vfaces_more_ = {};
  riders_ = {};
  if (!need) return;
  vfaces_.resize(dag_->heightfield().size());
  for (std::uint32_t f : active_)
    for (std::uint32_t s : dag_->face(f)) link_face(s, f);
}

void SelectiveRefinement::link_face(std::uint32_t s, std::uint32_t f) {
  SampleFaces& l = vfaces_[s];
  if (l.n < kInlineFaces)
    l.f[l.n] = f;
  else
    vfaces_more_[s].push_back(f);
  ++l.n;
}

// Removes f from s's faces; the last one takes its place.
void SelectiveRefinement::unlink_face(std::uint32_t s, std::uint32_t f) {
  SampleFaces& l = vfaces_[s];
  std::uint32_t last;
  if (l.n > kInlineFaces) {
    const auto more = vfaces_more_.find(s);
    last = more->second.back();
    more->second.pop_back();
    if (more->second.empty()) vfaces_more_.erase(more);
  } else {
    last = l.f[l.n - 1];
  }
  --l.n;
  if (last == f) return;
  const auto in = std::find(l.f.begin(), l.f.begin() + std::min(l.n, kInlineFaces), f);
  if (in != l.f.begin() + std::min(l.n, kInlineFaces)) {
    *in = last;
    return;
  }
  std::vector<std::uint32_t>& more = vfaces_more_.at(s);
  *std::find(more.begin(), more.end(), f) = last;
}

// Ends every geomorph at once: vertices jump to their samples, pending ecols are dropped
// (the next update decides again).
void SelectiveRefinement::stop_morphs() {
  for (const Morph& m : morphs_) morph_of_[m.sample] = kNone;
  morphs_.clear();
  riders_.clear();
}

std::array<double, 3> SelectiveRefinement::rest(std::uint32_t s) const {
  const std::uint32_t W = std::uint32_t(dag_->heightfield().width());
  return {double(s % W), double(s / W), dag_->heightfield()[s]};
}

std::vector<SelectiveRefinement::MorphState> SelectiveRefinement::morph_states() const {
  std::vector<MorphState> out;
  out.reserve(morphs_.size());
  for (const Morph& m : morphs_)
    out.push_back(MorphState{m.sample, m.from, m.to, m.t0, m.anchor == kNone ? m.t1 : INFINITY, m.anchor,
                             m.collapse != kNone});
  return out;
}

std::array<double, 3> SelectiveRefinement::displayed(std::uint32_t s) const {
  const std::uint32_t i = morph_of_[s];
  if (i == kNone) return rest(s);
  const Morph& m = morphs_[i];
  if (m.anchor != kNone) return displayed(m.anchor);
  const double a = (time_ - m.t0) / (m.t1 - m.t0);
  if (!(a < 1.0)) return m.to;
  if (!(a > 0.0)) return m.from;
  return {m.from[0] + (m.to[0] - m.from[0]) * a, m.from[1] + (m.to[1] - m.from[1]) * a,
          m.from[2] + (m.to[2] - m.from[2]) * a};
}

// True when no corner of the faces c creates (w and u's link) is moving: a pending ecol then
// meets the same surface when it completes as when it started (the corners cannot start to
// move meanwhile: they are present, so no vsplit moves them, and no ecol of theirs can be on
// the frontier while c is, because it would remove one of the faces c removes).
bool SelectiveRefinement::corners_at_rest(std::uint32_t c) const {
  const auto [f0, f1] = dag_->created_faces(c);
  for (std::uint32_t f = f0; f < f1; ++f)
    for (std::uint32_t s : dag_->face(f))
      if (morph_of_[s] != kNone) return false;
  return morph_of_[dag_->collapse(c).w] == kNone;
}

// Starts the morphs of the vertices that the refinement pass made appear, in the order they
// appeared. Vertical: u starts at the height that the surface displayed before this update has
// at u's sample now (its corners may be moving), so that a chain of vsplits in one update
// does not pop at the samples where its vertices appear: walk from the face of c containing u
// up through the faces that replaced it, as long as their remover was undone in this pass.
// Full: u starts at w's displayed position (w appeared earlier in the list if it is new).
void SelectiveRefinement::start_vsplit_morphs(const Frame& fr) {
  const std::uint32_t W = std::uint32_t(dag_->heightfield().width());
  for (std::uint32_t c : appeared_) {
    const Collapse& k = dag_->collapse(c);
    if (opt_.morph_mode == MorphMode::Full) {
      // u rides on w (its new faces are degenerate or copies of w's) until release_anchored
      // lets it slide to its own sample.
      start_morph(k.u, kNone, rest(k.u), rest(k.u), /*anchor=*/k.w);
      continue;
    }
    const GridPoint p{int(k.u % W), int(k.u / W)};
    std::uint32_t x = c, face = kNone;
    std::int64_t wt[3] = {0, 0, 0};
    for (;;) {
      face = kNone;
      const auto [f0, f1] = dag_->created_faces(x);
      for (std::uint32_t f = f0; f < f1 && face == kNone; ++f) {
        const auto& t = dag_->face(f);
        const GridPoint a{int(t[0] % W), int(t[0] / W)}, b{int(t[1] % W), int(t[1] / W)},
            d{int(t[2] % W), int(t[2] / W)};
        wt[0] = orient2d(b, d, p), wt[1] = orient2d(d, a, p), wt[2] = orient2d(a, b, p);
        if (wt[0] >= 0 && wt[1] >= 0 && wt[2] >= 0) face = f;
      }
      if (face == kNone) break;  // not reached: the faces of x cover u's sample
      const std::uint32_t r = dag_->remover(face);
      if (r == kNone || !undone_now_[r]) break;
      x = r;
    }
    // Everything that changes around u (the faces x created, before; the finer ones, after)
    // lies in volume(x): when it is outside the view, nothing visible moves, u pops.
    if (outside_view(fr, x)) continue;
    std::array<double, 3> from = rest(k.u);
    if (face != kNone) {
      const auto& t = dag_->face(face);
      from[2] = (double(wt[0]) * displayed(t[0])[2] + double(wt[1]) * displayed(t[1])[2] +
                 double(wt[2]) * displayed(t[2])[2]) /
                double(wt[0] + wt[1] + wt[2]);
    }
    start_morph(k.u, kNone, from, rest(k.u));
  }
  for (std::uint32_t c : appeared_) undone_now_[c] = 0;
  appeared_.clear();
}

// Height at u's sample of the displayed surface of the faces c creates (the surface once c is
// performed): the face containing u in plan view, interpolated from its corners' displayed
// heights with exact integer barycentric weights.
double SelectiveRefinement::coarse_height(std::uint32_t c) const {
  const std::uint32_t W = std::uint32_t(dag_->heightfield().width());
  const std::uint32_t u = dag_->collapse(c).u;
  const GridPoint p{int(u % W), int(u / W)};
  const auto [f0, f1] = dag_->created_faces(c);
  for (std::uint32_t f = f0; f < f1; ++f) {
    const auto& t = dag_->face(f);
    const GridPoint a{int(t[0] % W), int(t[0] / W)}, b{int(t[1] % W), int(t[1] / W)},
        d{int(t[2] % W), int(t[2] / W)};
    const std::int64_t wa = orient2d(b, d, p), wb = orient2d(d, a, p), wd = orient2d(a, b, p);
    if (wa < 0 || wb < 0 || wd < 0) continue;
    return (double(wa) * displayed(t[0])[2] + double(wb) * displayed(t[1])[2] +
            double(wd) * displayed(t[2])[2]) /
           double(wa + wb + wd);
  }
  return displayed(dag_->collapse(c).w)[2];  // not reached: the created faces cover u
}

void SelectiveRefinement::start_morph(std::uint32_t s, std::uint32_t collapse,
                                      const std::array<double, 3>& from, const std::array<double, 3>& to,
                                      std::uint32_t anchor) {
  Morph m{s, collapse, time_, anchor == kNone ? time_ + opt_.morph_seconds : 1e300, from, to, anchor};
  if (anchor != kNone) riders_[anchor].push_back(s);
  if (morph_of_[s] != kNone) {
    Morph& old = morphs_[morph_of_[s]];
    if (old.anchor != kNone) drop_rider(old.anchor, s);
    old = m;
    return;
  }
  morph_of_[s] = std::uint32_t(morphs_.size());
  morphs_.push_back(m);
}

// Vertices riding on an anchor that has stopped start moving from it to their own sample (a
// vertex riding on one released here keeps riding: its anchor now moves).
void SelectiveRefinement::release_anchored() {
  // Coarser vertices go first (a vertex's successors must not ride when it leaves); passes
  // repeat so that a whole chain released in one update starts sliding at once.
  for (bool released = true; released;) {
    released = false;
    for (Morph& m : morphs_) {
      if (m.anchor == kNone) continue;
      bool coarser_waits = false;  // a successor's vertex still rides: it slides first
      for (std::uint32_t q : dag_->succs(dag_->removed_by(m.sample))) {
        const std::uint32_t i = morph_of_[dag_->collapse(q).u];
        coarser_waits |= i != kNone && morphs_[i].anchor != kNone;
      }
      if (coarser_waits) continue;
      const std::array<double, 3> from = displayed(m.anchor), to = rest(m.sample);
      if (!can_slide(m.sample, from, to)) continue;
      drop_rider(m.anchor, m.sample);
      m.from = from;
      m.to = to;
      m.anchor = kNone;
      m.t0 = time_;
      m.t1 = time_ + opt_.morph_seconds;
      released = true;
    }
  }
}

// Plan-view track of a vertex from now on, as planned: static, or linear from a (at t0) to b
// (at t1) then static. `blocking`: it moves towards a pending ecol, which may be cancelled
// (then it turns back): its neighbours wait.
SelectiveRefinement::Track SelectiveRefinement::track(std::uint32_t x) const {
  std::uint32_t v = x;
  for (std::uint32_t i = morph_of_[v]; i != kNone;) {
    const Morph& m = morphs_[i];
    if (m.anchor != kNone) {
      v = m.anchor;
      i = morph_of_[v];
      continue;
    }
    if (m.collapse != kNone) return {m.from[0], m.from[1], m.to[0], m.to[1], m.t0, m.t1, true};
    return {m.from[0], m.from[1], m.to[0], m.to[1], m.t0, m.t1, false};
  }
  const std::array<double, 3> r = rest(v);
  return {r[0], r[1], r[0], r[1], time_, time_, false};
}

// Full mode: may s (with the vertices riding on it, which move with it as if collapsed into
// it) start sliding from `from` to `to` now? Yes when no face around them would fold over
// before every planned motion ends: each vertex's plan-view track is piecewise linear in time,
// so a face's signed area is piecewise quadratic; its minimum on each piece is checked.
// Faces that already fold never arise: the start is the current (valid) configuration.
bool SelectiveRefinement::can_slide(std::uint32_t s, const std::array<double, 3>& from,
                                    const std::array<double, 3>& to) const {
  cluster_.assign(1, s);
  for (std::size_t i = 0; i < cluster_.size(); ++i)
    if (const auto r = riders_.find(cluster_[i]); r != riders_.end())
      cluster_.insert(cluster_.end(), r->second.begin(), r->second.end());
  const Track mine{from[0], from[1], to[0], to[1], time_, time_ + opt_.morph_seconds, false};
  auto at = [](const Track& k, double t, double& x, double& y) {
    const double a = k.t1 > k.t0 ? std::clamp((t - k.t0) / (k.t1 - k.t0), 0.0, 1.0) : 1.0;
    x = k.ax + (k.bx - k.ax) * a, y = k.ay + (k.by - k.ay) * a;
  };
  const auto face_ok = [&](std::uint32_t f) {
    Track k[3];
    int in_cluster = 0;
    for (int j = 0; j < 3; ++j) {
      const std::uint32_t x = dag_->face(f)[j];
      if (std::find(cluster_.begin(), cluster_.end(), x) != cluster_.end()) {
        k[j] = mine;
        ++in_cluster;
      } else {
        k[j] = track(x);
        if (k[j].blocking) return false;
      }
    }
    if (in_cluster >= 2) return true;  // degenerate all along: two corners at one place
    // Pieces of [now, the last end]: every planned motion is linear between breakpoints.
    double tend = mine.t1;
    for (const Track& q : k) tend = std::max(tend, q.t1);
    std::array<double, 5> ts = {time_, mine.t1, std::clamp(k[0].t1, time_, tend),
                                std::clamp(k[1].t1, time_, tend), std::clamp(k[2].t1, time_, tend)};
    std::sort(ts.begin(), ts.end());
    ts[4] = tend;
    const int n = 5;
    for (int p = 0; p + 1 < n; ++p) {
      if (!(ts[p + 1] > ts[p])) continue;
      double x0[3], y0[3], x1[3], y1[3];
      for (int j = 0; j < 3; ++j) at(k[j], ts[p], x0[j], y0[j]), at(k[j], ts[p + 1], x1[j], y1[j]);
      // Corner j at s in [0, 1]: (x0 + s (x1 - x0), y0 + s (y1 - y0)); area2(s) = A + B s + C s^2.
      const double dx1 = x0[1] - x0[0], dy1 = y0[1] - y0[0], dx2 = x0[2] - x0[0], dy2 = y0[2] - y0[0];
      const double ex1 = (x1[1] - x0[1]) - (x1[0] - x0[0]), ey1 = (y1[1] - y0[1]) - (y1[0] - y0[0]);
      const double ex2 = (x1[2] - x0[2]) - (x1[0] - x0[0]), ey2 = (y1[2] - y0[2]) - (y1[0] - y0[0]);
      const double A = dx1 * dy2 - dy1 * dx2, B = dx1 * ey2 + ex1 * dy2 - dy1 * ex2 - ey1 * dx2,
                   C = ex1 * ey2 - ey1 * ex2;
      double lo = std::min(A, A + B + C);
      if (C > 0 && -B > 0 && -B < 2 * C) lo = std::min(lo, A - B * B / (4 * C));
      if (lo < -1e-9) return false;
    }
    return true;
  };
  for (std::uint32_t v : cluster_)
    if (!for_each_face_at(v, face_ok)) return false;
  return true;
}

void SelectiveRefinement::drop_rider(std::uint32_t anchor, std::uint32_t s) {
  const auto r = riders_.find(anchor);
  std::vector<std::uint32_t>& v = r->second;
  *std::find(v.begin(), v.end(), s) = v.back();
  v.pop_back();
  if (v.empty()) riders_.erase(r);
}

void SelectiveRefinement::end_morph(std::uint32_t s) {
  const std::uint32_t i = morph_of_[s];
  if (morphs_[i].anchor != kNone) drop_rider(morphs_[i].anchor, s);
  const std::uint32_t last = morphs_.back().sample;
  morphs_[i] = morphs_.back();
  morph_of_[last] = i;
  morphs_.pop_back();
  morph_of_[s] = kNone;
}

// A pending ecol of c that must not happen (c stopped being ok or left the frontier): u goes
// back to its sample, as fast as it came.
void SelectiveRefinement::cancel_pending(std::uint32_t c) {
  const std::uint32_t u = dag_->collapse(c).u, i = morph_of_[u];
  if (i == kNone || morphs_[i].collapse != c) return;
  const Morph m = morphs_[i];
  const double done = std::clamp((time_ - m.t0) / (m.t1 - m.t0), 0.0, 1.0);
  if (!(done > 0.0)) {
    end_morph(u);
    return;
  }
  morphs_[i] = Morph{u, kNone, time_, time_ + done * (m.t1 - m.t0), displayed(u), rest(u)};
}

}  // namespace terralod::pm
