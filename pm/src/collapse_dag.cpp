// CollapseDag: one replay of a PM's collapses on per-vertex face lists, recording every face
// each collapse removes and creates, the predecessor DAG, saturated errors and nested volumes.
//
// Paper: seeds/view-dependent-pm-dynamic-loading.txt, sections 2-3 (vertex hierarchy, Fig. 4
// bounding spheres); the face-based dependencies are those of a multi-triangulation (see the
// header for why they make every closed set of collapses a valid, error-bounded mesh).
// Memory: see the header. The replay keeps one std::vector of face ids per sample (~60-80
// bytes per vertex) until it ends.
#include "terralod/pm/collapse_dag.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "terralod/pm/linf_error.hpp"
#include "terralod/pm/memory_bytes.hpp"

namespace terralod::pm {
namespace {

void erase_one(std::vector<std::uint32_t>& v, std::uint32_t x) {
  auto it = std::find(v.begin(), v.end(), x);
  if (it == v.end()) throw std::logic_error("collapse dag: face list out of sync");
  *it = v.back();
  v.pop_back();
}

std::invalid_argument bad(std::size_t c, const std::string& what) {
  return std::invalid_argument("collapse dag: collapse " + std::to_string(c) + " " + what);
}

// The float f stored for a bound v, relative to origin o, is the one whose o + f lies on the
// outer side of v: start at the nearest float and step outwards until it does (rounding in
// v - o and in o + f may each take it a little inwards).
float float_below(double v, double o) {
  float f = float(v - o);
  while (o + double(f) > v) f = std::nextafter(f, -INFINITY);
  return f;
}
float float_above(double v, double o) {
  float f = float(v - o);
  while (o + double(f) < v) f = std::nextafter(f, INFINITY);
  return f;
}

}  // namespace

Vec3 CollapseDag::position(std::uint32_t s) const {
  const std::uint32_t W = std::uint32_t(hf_.width());
  return position(double(s % W), double(s / W), hf_[s]);
}

Vec3 CollapseDag::position(double col, double row, double z) const {
  const auto [x, y] = hf_.transform.to_world(col, row);
  return {x, y, z};
}

void CollapseDag::set_box(std::uint32_t c, const Box& b) {
  // Rounded outwards, so that what box() returns (origin + float) holds the exact box.
  const double ox = hf_.transform.x0, oy = hf_.transform.y0;
  boxes_[c] = {{float_below(b.lo.x, ox), float_below(b.lo.y, oy), float_below(b.lo.z, 0.0)},
               {float_above(b.hi.x, ox), float_above(b.hi.y, oy), float_above(b.hi.z, 0.0)},
               float_above(saturated_[c], 0.0),
               0.0f};
}

std::size_t CollapseDag::skip_for_floor(const ProgressiveMesh& pm, double floor_m) {
  // The saturated error of a dropped collapse is at most the largest error before it (its
  // predecessors come first in build order), so a prefix whose errors stay within floor_m
  // leaves faces within floor_m.
  const std::vector<Collapse>& cs = pm.collapses();
  std::size_t s = 0;
  while (s < cs.size() && cs[s].error <= floor_m) ++s;
  return s;
}

CollapseDag::CollapseDag(const ProgressiveMesh& pm, const DagOptions& options)
    : hf_(pm.heightfield()), kind_(options.volume) {
  const std::vector<Collapse>& all = pm.collapses();
  const std::size_t skip = std::min(options.skip, all.size());
  skipped_ = skip;
  collapses_.assign(all.begin() + std::ptrdiff_t(skip), all.end());
  const std::size_t n = collapses_.size();
  const std::uint32_t slots = std::uint32_t(pm.full_face_slots());
  const std::uint32_t W = std::uint32_t(hf_.width());

  // Full-resolution faces and per-sample face lists.
  faces_.assign(slots, {kNone, kNone, kNone});
  std::vector<std::vector<std::uint32_t>> star(hf_.size());
  std::array<std::uint32_t, 3> t;
  for (std::uint32_t f = 0; f < slots; ++f) {
    if (!pm.full_face(f, t)) continue;
    faces_[f] = t;
    for (std::uint32_t v : t) star[v].push_back(f);
  }
  creator_.assign(slots, kNone);
  removed_by_.assign(hf_.size(), kNone);

  auto point = [W](std::uint32_t s) { return GridPoint{int(s % W), int(s / W)}; };

  // One collapse u -> w on the face lists: removes u's star (on_removed(f) for each face) and
  // creates, for each of its faces without w, the face with u replaced by w (creator `label`).
  const auto replay = [&](std::size_t c, std::uint32_t label, auto&& on_removed) {
    const std::uint32_t u = all[c].u, w = all[c].w;
    std::vector<std::uint32_t> ring = std::move(star[u]);
    star[u] = {};
    int shared = 0;
    for (std::uint32_t f : ring) shared += (faces_[f][0] == w || faces_[f][1] == w || faces_[f][2] == w);
    if (shared < 1 || shared > 2) throw bad(c, "does not collapse an edge of the mesh");
    for (std::uint32_t f : ring) {
      on_removed(f);
      const std::array<std::uint32_t, 3> v = faces_[f];
      for (std::uint32_t x : v)
        if (x != u) erase_one(star[x], f);
      if (v[0] == w || v[1] == w || v[2] == w) continue;
      std::array<std::uint32_t, 3> nv = v;
      for (std::uint32_t& x : nv)
        if (x == u) x = w;
      if (orient2d(point(nv[0]), point(nv[1]), point(nv[2])) <= 0) throw bad(c, "flips a face");
      const std::uint32_t g = std::uint32_t(faces_.size());
      faces_.push_back(nv);
      creator_.push_back(label);
      for (std::uint32_t x : nv) star[x].push_back(g);
    }
  };

  if (skip > 0) {
    // The skipped collapses, on the face lists only, with their saturated errors; then the
    // faces left become the leaves (ids 0 .. L-1 in the order of their old ids), each with the
    // saturated error of the collapse that made it as its error.
    faces_.reserve(std::size_t(slots) + 2 * skip);
    std::vector<double> sat(skip);
    for (std::size_t c = 0; c < skip; ++c) {
      double e = all[c].error;
      replay(c, std::uint32_t(c), [&](std::uint32_t f) {
        if (creator_[f] != kNone) e = std::max(e, sat[creator_[f]]);
      });
      sat[c] = e;
    }
    std::vector<std::uint32_t> leaf_id(faces_.size(), kNone);
    for (const auto& s : star)
      for (std::uint32_t f : s) leaf_id[f] = 0;
    std::vector<std::array<std::uint32_t, 3>> leaves;
    for (std::uint32_t f = 0; f < leaf_id.size(); ++f) {
      if (leaf_id[f] == kNone) continue;
      leaf_id[f] = std::uint32_t(leaves.size());
      leaves.push_back(faces_[f]);
      // Rounded up to a float: the bound it gives stays true, in half the bytes.
      leaf_error_.push_back(float_above(creator_[f] == kNone ? 0.0 : sat[creator_[f]], 0.0));
    }
    // No leaf moved off the samples (only collapses of error 0 were skipped): no list needed.
    if (std::all_of(leaf_error_.begin(), leaf_error_.end(), [](float e) { return e == 0.0f; }))
      leaf_error_ = {};
    for (auto& s : star)
      for (std::uint32_t& f : s) f = leaf_id[f];
    faces_ = std::move(leaves);
    creator_.assign(faces_.size(), kNone);
  }
  created_base_ = std::uint32_t(faces_.size());
  for (std::uint32_t f = 0; f < created_base_; ++f)
    if (faces_[f][0] != kNone) full_faces_.push_back(f);
  for (const auto& s : star) full_vertex_count_ += s.empty() ? 0 : 1;
  faces_.reserve(faces_.size() + 4 * n);
  for (float e : leaf_error_) floor_error_ = std::max(floor_error_, double(e));

  // Replay of the DAG's collapses, recording what each removes and creates and its predecessors.
  removed_off_.assign(1, 0);
  created_off_.assign(1, 0);
  removed_.reserve(6 * n);
  std::vector<std::uint32_t> pred_list;  // flat (c, p) pairs, deduplicated per c
  std::vector<std::uint32_t> pred_first;
  pred_first.reserve(n + 1);
  std::vector<double> leaf_sat(leaf_error_.empty() ? 0 : n, 0.0);  // largest error of a removed leaf
  for (std::size_t c = 0; c < n; ++c) {
    pred_first.push_back(std::uint32_t(pred_list.size()));
    replay(skip + c, std::uint32_t(c), [&](std::uint32_t f) {
      removed_.push_back(f);
      const std::uint32_t p = creator_[f];
      if (p == kNone) {
        if (!leaf_sat.empty()) leaf_sat[c] = std::max(leaf_sat[c], double(leaf_error_[f]));
      } else if (std::find(pred_list.begin() + pred_first.back(), pred_list.end(), p) == pred_list.end()) {
        pred_list.push_back(p);
      }
    });
    removed_off_.push_back(std::uint32_t(removed_.size()));
    created_off_.push_back(std::uint32_t(faces_.size() - created_base_));
    removed_by_[collapses_[c].u] = std::uint32_t(c);
  }
  pred_first.push_back(std::uint32_t(pred_list.size()));
  star = {};
  remover_.assign(faces_.size(), kNone);
  for (std::size_t c = 0; c < n; ++c)
    for (std::uint32_t k = removed_off_[c]; k < removed_off_[c + 1]; ++k)
      remover_[removed_[k]] = std::uint32_t(c);

  // DAG in both directions.
  pred_off_ = std::move(pred_first);
  preds_ = std::move(pred_list);
  succ_off_.assign(n + 1, 0);
  for (std::uint32_t p : preds_) ++succ_off_[p + 1];
  for (std::size_t c = 0; c < n; ++c) succ_off_[c + 1] += succ_off_[c];
  succs_.resize(preds_.size());
  {
    std::vector<std::uint32_t> at(succ_off_.begin(), succ_off_.end() - 1);
    for (std::size_t c = 0; c < n; ++c)
      for (std::uint32_t p : preds(std::uint32_t(c))) succs_[at[p]++] = std::uint32_t(c);
  }

  // Saturated errors and nested volumes, in build order (predecessors come first).
  saturated_.resize(n);
  if (kind_ == VolumeKind::Box)
    boxes_.resize(n);
  else
    spheres_.resize(n);
  std::vector<Vec3> pts;
  double zlo = 1e300, zhi = -1e300;  // height range of the valid samples
  for (std::size_t i = 0; i < hf_.size(); ++i)
    if (hf_.valid(i)) zlo = std::min(zlo, hf_[i]), zhi = std::max(zhi, hf_[i]);
  for (std::uint32_t c = 0; c < n; ++c) {
    const double e = collapses_[c].error;
    double sat = leaf_sat.empty() ? e : std::max(e, leaf_sat[c]);
    for (std::uint32_t p : preds(c)) sat = std::max(sat, saturated_[p]);
    saturated_[c] = sat;
    // Corners of the created faces; each face extruded by +-e lies in the box of its corners
    // grown by e vertically (the box of the prism's six corners).
    pts.clear();
    const auto [f0, f1] = created_faces(c);
    for (std::uint32_t f = f0; f < f1; ++f)
      for (std::uint32_t s : faces_[f]) pts.push_back(position(s));
    if (pts.empty()) pts.push_back(position(collapses_[c].w));  // a border collapse creates nothing
    Box b{pts[0], pts[0]};
    for (const Vec3& q : pts) {
      b.lo = {std::min(b.lo.x, q.x), std::min(b.lo.y, q.y), std::min(b.lo.z, q.z - e)};
      b.hi = {std::max(b.hi.x, q.x), std::max(b.hi.y, q.y), std::max(b.hi.z, q.z + e)};
    }
    if (kind_ == VolumeKind::Box) {
      for (std::uint32_t p : preds(c)) {
        const Box q = box(p);
        b.lo = {std::min(b.lo.x, q.lo.x), std::min(b.lo.y, q.lo.y), std::min(b.lo.z, q.lo.z)};
        b.hi = {std::max(b.hi.x, q.hi.x), std::max(b.hi.y, q.hi.y), std::max(b.hi.z, q.hi.z)};
      }
      b.lo.z = std::max(b.lo.z, zlo);
      b.hi.z = std::min(b.hi.z, zhi);
      set_box(c, b);
    } else {
      // Centre: the middle of the box of everything to enclose; radius: the farthest of the
      // extruded corners and of the predecessors' spheres (Fig. 4's rule, r >= |C - C_p| + r_p).
      for (std::uint32_t p : preds(c)) {
        const Sphere& q = spheres_[p];
        b.lo = {std::min(b.lo.x, q.center.x - q.radius), std::min(b.lo.y, q.center.y - q.radius),
                std::min(b.lo.z, q.center.z - q.radius)};
        b.hi = {std::max(b.hi.x, q.center.x + q.radius), std::max(b.hi.y, q.center.y + q.radius),
                std::max(b.hi.z, q.center.z + q.radius)};
      }
      Sphere s;
      s.center = {0.5 * (b.lo.x + b.hi.x), 0.5 * (b.lo.y + b.hi.y), 0.5 * (b.lo.z + b.hi.z)};
      double r = 0.0;
      for (const Vec3& q : pts) {
        const double dx = q.x - s.center.x, dy = q.y - s.center.y, dz = std::abs(q.z - s.center.z) + e;
        r = std::max(r, std::sqrt(dx * dx + dy * dy + dz * dz));
      }
      for (std::uint32_t p : preds(c)) {
        const Sphere& q = spheres_[p];
        const double dx = q.center.x - s.center.x, dy = q.center.y - s.center.y, dz = q.center.z - s.center.z;
        r = std::max(r, std::sqrt(dx * dx + dy * dy + dz * dz) + q.radius);
      }
      // Rounding of the distances above is far below a nanometre; one part in 1e12 covers it.
      s.radius = r * (1.0 + 1e-12) + 1e-9;
      spheres_[c] = s;
    }
  }
  // The lists grew by reservation or doubling; a block stays resident for a whole flight, so
  // what it does not use goes back (about 1.6 MB of 18.5 in a 257-sample block of N44W072).
  faces_.shrink_to_fit();
  creator_.shrink_to_fit();
  removed_.shrink_to_fit();
  preds_.shrink_to_fit();
  full_faces_.shrink_to_fit();
}

std::size_t CollapseDag::memory_bytes() const {
  return sizeof(*this) + hf_.size() * sizeof(double) + hf_.mask().size() + capacity_bytes(collapses_) +
         capacity_bytes(saturated_) + capacity_bytes(pred_off_) + capacity_bytes(preds_) +
         capacity_bytes(succ_off_) + capacity_bytes(succs_) + capacity_bytes(boxes_) +
         capacity_bytes(spheres_) + capacity_bytes(faces_) + capacity_bytes(creator_) +
         capacity_bytes(remover_) + capacity_bytes(removed_off_) + capacity_bytes(removed_) +
         capacity_bytes(created_off_) + capacity_bytes(full_faces_) + capacity_bytes(removed_by_) +
         capacity_bytes(leaf_error_);
}

}  // namespace terralod::pm
