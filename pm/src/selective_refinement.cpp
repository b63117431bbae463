// SelectiveRefinement's engine: the selection S and its two legal-operation lists (tops and
// frontier), the active faces, vsplit/ecol, and update() with its triangle-budget regulation.
// The view test and the bound are in selective_refinement_view.cpp, runtime geomorphs in
// selective_refinement_morphs.cpp, mesh output in selective_refinement_output.cpp.
//
// Paper: seeds/view-dependent-pm-dynamic-loading.txt, section 3; the guarantee argument is in
// selective_refinement.hpp (monotone test => the fixed point is S* = {c : ok(c)}) and the
// projection bound in view.cpp. Memory: see the header.
#include "terralod/pm/selective_refinement.hpp"

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>

#include "selective_refinement_frame.hpp"
#include "terralod/pm/memory_bytes.hpp"

namespace terralod::pm {

namespace {
constexpr std::uint32_t kNone = CollapseDag::kNone;

// Floats below / above v, cheaply: v moved outwards by 1e-7 of itself (more than the half unit
// in the last place that the conversion may round by) and by 1e-30 (near zero).
inline float float_below(double v) { return float(v - (std::abs(v) * 1e-7 + 1e-30)); }
inline float float_above(double v) { return float(v + (std::abs(v) * 1e-7 + 1e-30)); }

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
  morph_of_.assign(dag.heightfield().size(), kNone);
  scratch_index_.assign(dag.heightfield().size(), kNone);
  // No selection has more faces than the full-resolution mesh (every collapse removes one or
  // two), which the constructor starts from: those arrays get exactly that room.
  const std::size_t full = dag.full_faces().size();
  active_.reserve(full);
  face_rec_.reserve(full);
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
    if (const std::vector<Packed>& packed = dag.packed_boxes(); !packed.empty())
      for (std::uint32_t c : set->items) set->recs.push_back(packed[c]);
  track_adjacency();
  stats_.active_vertices = active_vertex_count();
  stats_.triangles = active_.size();
  stats_.tolerance_px = tau_;
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
  const Heightfield& hf = dag_->heightfield();
  face_rec_.push_back(FaceRec{{t[0], t[1], t[2]}, {hf[t[0]], hf[t[1]], hf[t[2]]}, dag_->face_error(f)});
  if (!defer_boxes_) push_face_box(face_rec_.back());
  if (!vfaces_.empty())
    for (std::uint32_t s : dag_->face(f)) link_face(s, f);
}

// The records tops_ and frontier_ keep beside their items: none while the constructor
// descends to the base mesh (they are made at the end), and none without boxes.
const std::vector<SelectiveRefinement::Packed>& SelectiveRefinement::list_records() const {
  static const std::vector<Packed> none;
  return defer_boxes_ ? none : dag_->packed_boxes();
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
    for (std::uint32_t s : dag_->face(f)) unlink_face(s, f);
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

// --- Update ------------------------------------------------------------------------------------

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

std::size_t SelectiveRefinement::full_memory_bytes(const CollapseDag& dag, const RefinementOptions& options) {
  const std::size_t n = dag.collapse_count(), samples = dag.heightfield().size(),
                    faces = dag.full_faces().size();
  // As the constructor sizes them: per collapse in_s_ and undone_now_ (a byte each), preds_out_,
  // succs_in_ and both lists' positions (4 bytes each); face_pos_; per sample morph_of_ and
  // scratch_index_; active_ and face_rec_, reserved for the full-resolution faces; the faces'
  // float boxes and errors, grown by doubling from the base mesh's.
  std::size_t bytes = sizeof(SelectiveRefinement) + n * (2 + 4 * sizeof(std::uint32_t)) +
                      dag.face_id_count() * sizeof(std::uint32_t) + samples * 2 * sizeof(std::uint32_t) +
                      faces * (sizeof(std::uint32_t) + sizeof(FaceRec)) +
                      std::bit_ceil(faces) * 7 * sizeof(float);
  // Fully refined, the frontier is every collapse without predecessors, each with its record
  // (the list grows by doubling). No collapse is a top then, but the tops' list keeps the room
  // of the selections on the way, counted here as the frontier's: measured on N44W072's blocks
  // of 257, refined from the base mesh, both lists ended at 8192 records. An update's work
  // list (an item and a verdict each) is loaded from one of them.
  std::size_t first = 0;
  for (std::uint32_t c = 0; c < n; ++c) first += dag.preds(c).empty();
  bytes += std::bit_ceil(first) *
           (2 * (sizeof(std::uint32_t) + (dag.packed_boxes().empty() ? 0 : sizeof(Packed))) +
            sizeof(std::uint32_t) + sizeof(std::int8_t));
  if (options.morph_seconds > 0.0 && options.morph_mode == MorphMode::Full) {
    // Each sample's faces: kInlineFaces in place, the rest in a map node with a list (grown by
    // doubling) and a bucket. No rider without morphs.
    std::vector<std::uint32_t> degree(samples, 0);
    for (std::uint32_t f : dag.full_faces())
      for (std::uint32_t s : dag.face(f)) ++degree[s];
    bytes += samples * sizeof(SampleFaces);
    for (std::uint32_t d : degree)
      if (d > kInlineFaces)
        bytes += 2 * sizeof(void*) + detail::hash_node_bytes<std::uint32_t, std::vector<std::uint32_t>>() +
                 std::bit_ceil(d - kInlineFaces) * sizeof(std::uint32_t);
  }
  return bytes;
}

std::size_t SelectiveRefinement::memory_bytes() const {
  std::size_t n = sizeof(*this) + capacity_bytes(in_s_) + capacity_bytes(preds_out_) +
                  capacity_bytes(succs_in_) + capacity_bytes(active_) + capacity_bytes(face_pos_) +
                  capacity_bytes(face_rec_) + capacity_bytes(ferr_) + capacity_bytes(morphs_) +
                  capacity_bytes(morph_of_) + capacity_bytes(vfaces_) + capacity_bytes(vfaces_more_) +
                  capacity_bytes(riders_) + capacity_bytes(cluster_) + capacity_bytes(work_) +
                  capacity_bytes(work_verdict_) + capacity_bytes(appeared_) + capacity_bytes(undone_now_) +
                  capacity_bytes(scratch_index_);
  for (const IndexSet* s : {&tops_, &frontier_})
    n += capacity_bytes(s->items) + capacity_bytes(s->pos) + capacity_bytes(s->recs);
  for (const auto& b : fbox_) n += capacity_bytes(b);
  return n;
}

}  // namespace terralod::pm
