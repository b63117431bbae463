// SelectiveRefinement: incremental vertex-front updates (vsplit/ecol over the collapse DAG),
// the screen-space test, triangle-budget regulation and runtime geomorphs.
//
// Paper: seeds/view-dependent-pm-dynamic-loading.txt, section 3; the guarantee argument is in
// selective_refinement.hpp (monotone test => the fixed point is S* = {c : ok(c)}) and the
// projection bound in view.cpp. Memory: see the header.
#include "terralod/pm/selective_refinement.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <numeric>
#include <optional>
#include <stdexcept>

namespace terralod::pm {

namespace {
constexpr std::uint32_t kNone = CollapseDag::kNone;

// Floats below / above v, cheaply: v moved outwards by 1e-7 of itself (more than the half unit
// in the last place that the conversion may round by) and by 1e-30 (near zero).
inline float float_below(double v) { return float(v - (std::abs(v) * 1e-7 + 1e-30)); }
inline float float_above(double v) { return float(v + (std::abs(v) * 1e-7 + 1e-30)); }

// Floats nearest to v below / above (v within float range).
float round_down(double v) {
  const float f = float(v);
  return double(f) <= v ? f : std::nextafter(f, -INFINITY);
}
float round_up(double v) {
  const float f = float(v);
  return double(f) >= v ? f : std::nextafter(f, INFINITY);
}

void check_options(const RefinementOptions& o) {
  auto fail = [](const char* what) {
    throw std::invalid_argument(std::string("selective refinement: ") + what);
  };
  if (!(o.tolerance_px > 0.0) || !std::isfinite(o.tolerance_px)) fail("tolerance_px must be > 0");
  if (!(o.budget_gain > 0.0 && o.budget_gain <= 2.0)) fail("budget_gain must be in (0, 2]");
  if (!(o.min_tolerance_px > 0.0) || !(o.max_tolerance_px >= o.min_tolerance_px) ||
      !std::isfinite(o.max_tolerance_px))
    fail("need 0 < min_tolerance_px <= max_tolerance_px");
  if (!(o.morph_seconds >= 0.0) || !std::isfinite(o.morph_seconds)) fail("morph_seconds must be >= 0");
  if (!(o.cull_margin >= 1.0 && o.cull_margin <= 10.0)) fail("cull_margin must be in [1, 10]");
}
}  // namespace

// View constants of one update.
struct SelectiveRefinement::Frame {
  const View* view = nullptr;
  const View* cull = nullptr;  // the view, or its frustum widened by cull_margin
  double kf = 0.0;             // K * vertical_factor / tau: ok when E * kf <= max(zmin, near)
  double kvf = 0.0;            // K * vertical_factor
  double near = 0.0;
  double fz = 0.0;  // |forward.z|: depth change per metre of height
  // depth(col, row, z) = d0 + dc col + dr row + dz z (the transform is affine).
  double d0 = 0.0, dc = 0.0, dr = 0.0, dz = 0.0, inv_w = 0.0;
  double floor = -1.0;  // face_bound_px skips the plane tests below this value
  std::uint32_t w = 0;
  std::size_t evaluated = 0;

  Frame(const View& v, const Heightfield& hf, double tau) : view(&v), cull(&v) {
    kvf = v.focal_px() * v.vertical_factor();
    kf = kvf / tau;
    near = v.camera().near_m;
    fz = std::abs(v.forward().z);
    const GridTransform& t = hf.transform;
    const Vec3& f = v.forward();
    d0 = (t.x0 - v.eye().x) * f.x + (t.y0 - v.eye().y) * f.y - v.eye().z * f.z;
    dc = t.xc * f.x + t.yc * f.y;
    dr = t.xr * f.x + t.yr * f.y;
    dz = f.z;
    w = std::uint32_t(hf.width());
    inv_w = 1.0 / double(hf.width());
    set_cull(v, hf);
  }
  // Coordinates relative to the packed records' origin (x0, y0, 0) of the transform.
  double pd0 = 0.0, pf[3] = {0, 0, 0};  // depth = pd0 + pf . p
  double pl[6][4] = {};                 // cull planes: n . p + d
  void set_cull(const View& c, const Heightfield& hf) {
    cull = &c;
    const Vec3 o{hf.transform.x0, hf.transform.y0, 0.0};
    const Vec3& f = view->forward();
    pf[0] = f.x, pf[1] = f.y, pf[2] = f.z;
    pd0 = dot(o, f) - dot(view->eye(), f);
    for (int k = 0; k < 6; ++k) {
      const Plane& q = c.planes()[std::size_t(k)];
      pl[k][0] = q.n.x, pl[k][1] = q.n.y, pl[k][2] = q.n.z, pl[k][3] = q.distance(o);
    }
  }
};

SelectiveRefinement::SelectiveRefinement(const CollapseDag& dag, const RefinementOptions& options)
    : dag_(&dag), opt_(options) {
  check_options(opt_);
  tau_ = opt_.tolerance_px;
  const std::size_t n = dag.collapse_count();
  in_s_.assign(n, 0);
  preds_out_.resize(n);
  succs_in_.assign(n, 0);
  tops_.pos.assign(n, kNone);
  frontier_.pos.assign(n, kNone);
  undone_now_.assign(n, 0);
  face_pos_.assign(dag.face_id_count(), kNone);
  zlo_ = 1e300, zhi_ = -1e300;
  for (std::size_t i = 0; i < dag.heightfield().size(); ++i)
    if (dag.heightfield().valid(i))
      zlo_ = std::min(zlo_, dag.heightfield()[i]), zhi_ = std::max(zhi_, dag.heightfield()[i]);
  {
    const GridTransform& g = dag.heightfield().transform;
    const double w = dag.heightfield().width(), h = dag.heightfield().height();
    coord_scale_ = w * (std::abs(g.xc) + std::abs(g.yc)) + h * (std::abs(g.xr) + std::abs(g.yr)) +
                   std::max(std::abs(zlo_), std::abs(zhi_));
  }
  if (dag.volume_kind() == VolumeKind::Box) {
    // Boxes relative to (x0, y0, 0) in floats, rounded outwards, and saturated errors rounded
    // up: the test stays conservative and reads one 32-byte record.
    const double ox = dag.heightfield().transform.x0, oy = dag.heightfield().transform.y0;
    auto down = round_down;
    auto up = round_up;
    packed_.resize(n);
    for (std::uint32_t c = 0; c < n; ++c) {
      const Box& b = dag.box(c);
      packed_[c] = {{down(b.lo.x - ox), down(b.lo.y - oy), down(b.lo.z)},
                    {up(b.hi.x - ox), up(b.hi.y - oy), up(b.hi.z)},
                    up(dag.saturated_error(c)),
                    0.0f};
    }
  }
  morph_of_.assign(dag.heightfield().size(), kNone);
  scratch_index_.assign(dag.heightfield().size(), kNone);
  // The float boxes of the faces, and the records beside the tops and the frontier, are made
  // once, for the base mesh, not for everything that appears on the way there.
  defer_boxes_ = true;
  for (std::uint32_t f : dag.full_faces()) add_face(f);
  for (std::uint32_t c = 0; c < n; ++c) {
    preds_out_[c] = std::uint32_t(dag.preds(c).size());
    if (preds_out_[c] == 0) frontier_.insert(c, list_records());
  }
  // Start at the base mesh: build order is a topological order of the DAG.
  for (std::uint32_t c = 0; c < n; ++c) perform(c);
  defer_boxes_ = false;
  for (const FaceRec& r : face_rec_) push_face_box(r);
  for (IndexSet* set : {&tops_, &frontier_})
    if (!packed_.empty())
      for (std::uint32_t c : set->items) set->recs.push_back(packed_[c]);
  track_adjacency();
  stats_.active_vertices = active_vertex_count();
  stats_.triangles = active_.size();
  stats_.tolerance_px = tau_;
}

// Full geomorphs need each vertex's current faces (to keep neighbours from sliding together);
// the lists are kept only then.
void SelectiveRefinement::track_adjacency() {
  const bool need = opt_.morph_seconds > 0.0 && opt_.morph_mode == MorphMode::Full;
  if (need == !vfaces_.empty()) return;
  vfaces_.clear();
  riders_.clear();
  if (!need) return;
  vfaces_.resize(dag_->heightfield().size());
  riders_.resize(dag_->heightfield().size());
  for (std::uint32_t f : active_)
    for (std::uint32_t s : dag_->face(f)) vfaces_[s].push_back(f);
}

void SelectiveRefinement::set_options(const RefinementOptions& options) {
  check_options(options);
  if (options.morph_mode != opt_.morph_mode || options.morph_seconds != opt_.morph_seconds) stop_morphs();
  opt_ = options;
  tau_ = opt_.tolerance_px;
  track_adjacency();
}

// --- Faces and the two legal-operation lists ---------------------------------------------------

void SelectiveRefinement::add_face(std::uint32_t f) {
  face_pos_[f] = std::uint32_t(active_.size());
  active_.push_back(f);
  const auto& t = dag_->face(f);
  const std::uint32_t c = dag_->creator(f);
  const Heightfield& hf = dag_->heightfield();
  face_rec_.push_back(FaceRec{
      {t[0], t[1], t[2]}, {hf[t[0]], hf[t[1]], hf[t[2]]}, c == kNone ? 0.0 : dag_->collapse(c).error});
  if (!defer_boxes_) push_face_box(face_rec_.back());
  if (!vfaces_.empty())
    for (std::uint32_t s : dag_->face(f)) vfaces_[s].push_back(f);
}

// The records tops_ and frontier_ keep beside their items: none while the constructor
// descends to the base mesh (they are made at the end), and none without boxes.
const std::vector<SelectiveRefinement::Packed>& SelectiveRefinement::list_records() const {
  static const std::vector<Packed> none;
  return defer_boxes_ ? none : packed_;
}

// Appends the float box of the face's clipped prism (as face_bound_px sees it) relative to
// (x0, y0, 0), rounded outwards, and its error rounded up, to fbox_ and ferr_.
void SelectiveRefinement::push_face_box(const FaceRec& r) {
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  const GridTransform& g = dag_->heightfield().transform;
  const std::uint32_t W = std::uint32_t(dag_->heightfield().width());
  const double inv_w = 1.0 / double(W);
  for (int k = 0; k < 3; ++k) {
    const std::uint32_t rw = std::uint32_t((double(r.s[k]) + 0.5) * inv_w);  // = s / W (face_bound_px)
    const double col = double(r.s[k] - rw * W), row = double(rw);
    const double x = col * g.xc + row * g.xr, y = col * g.yc + row * g.yr;
    lo[0] = std::min(lo[0], x), hi[0] = std::max(hi[0], x);
    lo[1] = std::min(lo[1], y), hi[1] = std::max(hi[1], y);
    lo[2] = std::min(lo[2], std::max(r.z[k] - r.error, zlo_));
    hi[2] = std::max(hi[2], std::min(r.z[k] + r.error, zhi_));
  }
  for (int a = 0; a < 3; ++a)
    fbox_[2 * a].push_back(float_below(lo[a])), fbox_[2 * a + 1].push_back(float_above(hi[a]));
  ferr_.push_back(float_above(r.error));
}

void SelectiveRefinement::remove_face(std::uint32_t f) {
  const std::uint32_t p = face_pos_[f], last = active_.back();
  active_[p] = last;
  face_rec_[p] = face_rec_.back();
  face_pos_[last] = p;
  active_.pop_back();
  face_rec_.pop_back();
  if (!defer_boxes_) {
    for (std::vector<float>& v : fbox_) v[p] = v.back(), v.pop_back();
    ferr_[p] = ferr_.back(), ferr_.pop_back();
  }
  face_pos_[f] = kNone;
  if (!vfaces_.empty())
    for (std::uint32_t s : dag_->face(f)) {
      std::vector<std::uint32_t>& v = vfaces_[s];
      *std::find(v.begin(), v.end(), f) = v.back();
      v.pop_back();
    }
}

void SelectiveRefinement::perform(std::uint32_t c) {
  for (std::uint32_t f : dag_->removed_faces(c)) remove_face(f);
  const auto [f0, f1] = dag_->created_faces(c);
  for (std::uint32_t f = f0; f < f1; ++f) add_face(f);
  in_s_[c] = 1;
  ++performed_;
  frontier_.erase(c);
  tops_.insert(c, list_records());  // no successor can be in S: S is closed and c was not in it
  for (std::uint32_t p : dag_->preds(c))
    if (succs_in_[p]++ == 0) tops_.erase(p);
  for (std::uint32_t s : dag_->succs(c))
    if (--preds_out_[s] == 0) frontier_.insert(s, list_records());
  const std::uint32_t u = dag_->collapse(c).u;
  if (morph_of_[u] != kNone) end_morph(u);
}

void SelectiveRefinement::undo(std::uint32_t c, bool morph) {
  const auto [f0, f1] = dag_->created_faces(c);
  for (std::uint32_t f = f0; f < f1; ++f) remove_face(f);
  for (std::uint32_t f : dag_->removed_faces(c)) add_face(f);
  in_s_[c] = 0;
  --performed_;
  tops_.erase(c);
  frontier_.insert(c, list_records());  // its predecessors are all in S
  for (std::uint32_t p : dag_->preds(c))
    if (--succs_in_[p] == 0) tops_.insert(p, list_records());
  for (std::uint32_t s : dag_->succs(c))
    if (preds_out_[s]++ == 0) {
      frontier_.erase(s);
      cancel_pending(s);
    }
  if (morph) {  // the morph starts once the whole refinement pass is done (start_vsplit_morphs)
    undone_now_[c] = 1;
    appeared_.push_back(c);
  }
}

// Ends every geomorph at once: vertices jump to their samples, pending ecols are dropped
// (the next update decides again).
void SelectiveRefinement::stop_morphs() {
  for (const Morph& m : morphs_) morph_of_[m.sample] = kNone;
  morphs_.clear();
  for (auto& r : riders_) r.clear();
}

std::size_t SelectiveRefinement::vsplit(std::uint32_t c) {
  stop_morphs();
  std::size_t done = 0;
  work_.assign(1, c);
  while (!work_.empty()) {
    const std::uint32_t x = work_.back();
    if (!in_s_[x]) {
      work_.pop_back();
      continue;
    }
    std::uint32_t next = kNone;
    for (std::uint32_t s : dag_->succs(x))
      if (in_s_[s]) {
        next = s;
        break;
      }
    if (next != kNone) {
      work_.push_back(next);
      continue;
    }
    work_.pop_back();
    undo(x, /*morph=*/false);
    ++done;
  }
  return done;
}

std::size_t SelectiveRefinement::ecol(std::uint32_t c) {
  stop_morphs();
  std::size_t done = 0;
  work_.assign(1, c);
  while (!work_.empty()) {
    const std::uint32_t x = work_.back();
    if (in_s_[x]) {
      work_.pop_back();
      continue;
    }
    std::uint32_t next = kNone;
    for (std::uint32_t p : dag_->preds(x))
      if (!in_s_[p]) {
        next = p;
        break;
      }
    if (next != kNone) {
      work_.push_back(next);
      continue;
    }
    work_.pop_back();
    cancel_pending(x);
    perform(x);
    ++done;
  }
  return done;
}

// --- Geomorph state ----------------------------------------------------------------------------

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
    for (std::uint32_t r : riders_[cluster_[i]]) cluster_.push_back(r);
  const Track mine{from[0], from[1], to[0], to[1], time_, time_ + opt_.morph_seconds, false};
  auto at = [](const Track& k, double t, double& x, double& y) {
    const double a = k.t1 > k.t0 ? std::clamp((t - k.t0) / (k.t1 - k.t0), 0.0, 1.0) : 1.0;
    x = k.ax + (k.bx - k.ax) * a, y = k.ay + (k.by - k.ay) * a;
  };
  for (std::uint32_t v : cluster_)
    for (std::uint32_t f : vfaces_[v]) {
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
      if (in_cluster >= 2) continue;  // degenerate all along: two corners at one place
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
    }
  return true;
}

void SelectiveRefinement::drop_rider(std::uint32_t anchor, std::uint32_t s) {
  std::vector<std::uint32_t>& v = riders_[anchor];
  *std::find(v.begin(), v.end(), s) = v.back();
  v.pop_back();
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

// --- The view test -------------------------------------------------------------------------------

// 0: not ok (refine); 1: ok by the error test; 2: ok because volume(c) is outside the frustum.
int SelectiveRefinement::classify(Frame& fr, std::uint32_t c) const {
  ++fr.evaluated;
  if (!packed_.empty()) return classify_box(fr, packed_[c]);  // boxes: one 32-byte record per test
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

// --- Update ------------------------------------------------------------------------------------

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

const FrameStats& SelectiveRefinement::update(const View& view, double time_s) {
  const auto t_start = std::chrono::steady_clock::now();
  if (started_ && time_s < time_)
    throw std::invalid_argument("selective refinement: update time went backwards");
  if (!std::isfinite(time_s)) throw std::invalid_argument("selective refinement: update time must be finite");
  // Budget mode: regulate tau from the previous frame's triangle count (Hoppe 1998).
  if (opt_.target_triangles > 0 && started_) {
    const double ratio = double(std::max<std::size_t>(active_.size(), 1)) / double(opt_.target_triangles);
    const double factor = std::clamp(std::pow(ratio, opt_.budget_gain), 0.5, 2.0);
    tau_ = std::clamp(tau_ * factor, opt_.min_tolerance_px, opt_.max_tolerance_px);
  }
  // Nothing is displayed before the first update, so it does not morph.
  const bool morph = opt_.morph_seconds > 0.0 && started_;
  started_ = true;
  time_ = time_s;

  Frame fr(view, dag_->heightfield(), tau_);
  std::optional<View> widened;
  if (opt_.cull_margin > 1.0) {
    Camera c = view.camera();
    c.fovy_deg = 2.0 * std::atan(opt_.cull_margin * view.tan_half_fovy()) * 180.0 / std::numbers::pi;
    widened.emplace(c);
    fr.set_cull(*widened, dag_->heightfield());
  }
  FrameStats st;
  st.tolerance_px = tau_;

  // (1) Refine: undo every top that is not ok; its predecessors may become tops. With boxes,
  // the tops are tested first in one pass over their records (beside the list, so the pass
  // streams through memory) and only those to undo are queued, with their verdict; the order
  // of the undos is the same as testing each one when it is taken from the stack.
  prefilter(fr, tops_, /*want_ok=*/false);
  while (!work_.empty()) {
    const std::uint32_t c = work_.back();
    const int tested = work_verdict_.back();
    work_.pop_back(), work_verdict_.pop_back();
    if (!in_s_[c] || succs_in_[c] != 0 || (tested < 0 && classify(fr, c) != 0)) continue;
    undo(c, morph);
    ++st.vsplits;
    for (std::uint32_t p : dag_->preds(c))
      if (succs_in_[p] == 0) work_.push_back(p), work_verdict_.push_back(-1);
  }
  start_vsplit_morphs(fr);
  // (2) Pending ecols: cancel those no longer ok, perform those whose vertex has arrived.
  for (std::size_t i = 0; i < morphs_.size();) {
    const std::uint32_t c = morphs_[i].collapse;
    if (c == kNone) {
      ++i;
      continue;
    }
    if (classify(fr, c) == 0) {
      cancel_pending(c);  // slot i now holds a vsplit morph, or another morph
      continue;
    }
    if (time_ >= morphs_[i].t1 || outside_view(fr, c)) {
      perform(c);  // ends the morph: slot i now holds another one
      ++st.ecols;
      continue;
    }
    ++i;
  }
  // (3) Coarsen: perform (or start moving towards) every frontier collapse that is ok (with
  // boxes, the frontier is tested first in one pass, as the tops were).
  prefilter(fr, frontier_, /*want_ok=*/true);
  while (!work_.empty()) {
    const std::uint32_t c = work_.back();
    const int tested = work_verdict_.back();
    work_.pop_back(), work_verdict_.pop_back();
    if (in_s_[c] || preds_out_[c] != 0) continue;
    const Collapse& k = dag_->collapse(c);
    const std::uint32_t mu = morph_of_[k.u];
    if (mu != kNone && morphs_[mu].collapse == c) continue;  // already on its way
    const int verdict = tested < 0 ? classify(fr, c) : tested;
    if (verdict == 0) continue;
    const bool riding = mu != kNone && morphs_[mu].anchor == k.w;  // already where c puts it
    if (!morph || verdict == 2 || riding || outside_view(fr, c)) {
      perform(c);
      ++st.ecols;
      for (std::uint32_t s : dag_->succs(c))
        if (preds_out_[s] == 0) work_.push_back(s), work_verdict_.push_back(-1);
    } else if (corners_at_rest(c)) {
      if (opt_.morph_mode == MorphMode::Vertical) {
        std::array<double, 3> to = rest(k.u);
        to[2] = coarse_height(c);
        start_morph(k.u, c, displayed(k.u), to);
      } else {
        start_morph(k.u, c, displayed(k.u), rest(k.w));
      }
    }
  }
  // (4) Finished vsplit morphs; vertices riding on one that stopped start their own.
  for (std::size_t i = 0; i < morphs_.size();) {
    if (morphs_[i].collapse == kNone && morphs_[i].anchor == kNone && time_ >= morphs_[i].t1)
      end_morph(morphs_[i].sample);
    else
      ++i;
  }
  release_anchored();

  // Statistics and the guaranteed bound.
  const auto t_bound = std::chrono::steady_clock::now();
  double bound_m = 0.0;
  const double bound = filtered_bound_px(fr, bound_m);
  st.bound_px = bound;
  st.bound_m = bound_m;
  st.evaluated = fr.evaluated;
  st.active_vertices = active_vertex_count();
  st.triangles = active_.size();
  st.morphing = morphs_.size();
  for (const Morph& m : morphs_) st.pending_ecols += m.collapse != kNone;
  const auto t_end = std::chrono::steady_clock::now();
  st.update_ms = std::chrono::duration<double, std::milli>(t_end - t_start).count();
  st.bound_ms = std::chrono::duration<double, std::milli>(t_end - t_bound).count();
  stats_ = st;
  return stats_;
}

// --- Output --------------------------------------------------------------------------------------

namespace {
// Triangles given by corner(i) -> the three samples of triangle i (i < n) as vertices numbered in
// order of first use (samples) and triangles indexing them; `index` (per sample, all kNone on
// entry) is left as it was found.
template <class Corners>
void index_corners(std::size_t n, const Corners& corner, std::vector<std::uint32_t>& index,
                   std::vector<std::uint32_t>& samples,
                   std::vector<std::array<std::uint32_t, 3>>& triangles) {
  samples.clear();
  triangles.clear();
  triangles.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t* c = corner(i);
    std::array<std::uint32_t, 3> t;
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t s = c[k];
      if (index[s] == CollapseDag::kNone) {
        index[s] = std::uint32_t(samples.size());
        samples.push_back(s);
      }
      t[k] = index[s];
    }
    triangles.push_back(t);
  }
  for (std::uint32_t s : samples) index[s] = CollapseDag::kNone;
}
}  // namespace

void SelectiveRefinement::index_faces(const std::vector<std::uint32_t>& faces,
                                      std::vector<std::uint32_t>& samples,
                                      std::vector<std::array<std::uint32_t, 3>>& triangles) const {
  index_corners(
      faces.size(), [&](std::size_t i) { return dag_->face(faces[i]).data(); }, scratch_index_, samples,
      triangles);
}

TriangleMesh SelectiveRefinement::mesh() const {
  std::vector<std::uint32_t> faces = active_;
  std::sort(faces.begin(), faces.end());
  TriangleMesh m;
  index_faces(faces, m.vertices, m.triangles);
  for (std::uint32_t f : faces) {
    const std::uint32_t c = dag_->creator(f);
    if (c != kNone) m.error_bound = std::max(m.error_bound, dag_->saturated_error(c));
  }
  return m;
}

// The displayed mesh into `out` (its storage reused), the active faces read from face_rec_
// (parallel to active_: corners and error side by side, one pass over contiguous records), in
// the order `order` gives as positions in active_ (null: active_'s own order).
void SelectiveRefinement::render_into(const std::vector<std::uint32_t>* order, RenderMesh& out) const {
  const std::size_t n = face_rec_.size();
  auto at = [&](std::size_t i) -> const FaceRec& { return face_rec_[order ? (*order)[i] : i]; };
  index_corners(
      n, [&](std::size_t i) { return at(i).s; }, scratch_index_, out.samples, out.triangles);
  out.positions.clear();
  out.positions.reserve(out.samples.size());
  for (std::uint32_t s : out.samples) {
    const std::array<double, 3> p = displayed(s);
    out.positions.push_back(dag_->position(p[0], p[1], p[2]));
  }
  out.errors.resize(n);
  for (std::size_t i = 0; i < n; ++i) out.errors[i] = at(i).error;
}

void SelectiveRefinement::render_mesh_into(RenderMesh& out) const { render_into(nullptr, out); }

RenderMesh SelectiveRefinement::render_mesh() const {
  std::vector<std::uint32_t> order(active_.size());  // ordered by face id, like mesh()
  std::iota(order.begin(), order.end(), 0u);
  std::sort(order.begin(), order.end(),
            [&](std::uint32_t a, std::uint32_t b) { return active_[a] < active_[b]; });
  RenderMesh r;
  render_into(&order, r);
  return r;
}

}  // namespace terralod::pm
