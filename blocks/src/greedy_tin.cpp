// Greedy-insertion TIN of heightfield samples with an exact L-infinity error.
//
// Algorithm: Garland & Heckbert, "Fast polygonal approximation of terrains and height fields"
// (1995), algorithm III ("greedy insertion", the one behind delatin/hmm): an incremental
// Delaunay triangulation in (col,row) keeps, per triangle, its exact error and the sample where it
// is largest; a max-heap of triangles gives the next sample to insert; after an insertion only the
// triangles created or changed by the split and the Delaunay flips (Lawson's legalisation) are
// re-scanned. Predicates are exact: orientation in 64-bit and the in-circle test in 128-bit
// integers on integer sample coordinates. Under ErrorMetric::Continuous a triangle's error also
// includes the crossings of its edges with the full-resolution grid edges (pm::LInfError, Eq. 1
// of the view-dependent PM paper); when such a crossing is the worst point, the nearer endpoint of
// the crossed grid edge is inserted. The polygon variant starts from an ear-clipping
// triangulation of the polygon made constrained-Delaunay by Lawson flips; boundary edges have no
// twin and are never flipped, so the boundary stays the polygon's.
//
// Memory: 5 bytes per sample of the domain's bounding box (sample -> vertex map, inside mask)
// plus about 90 bytes per triangle (vertices, twins, errors, candidate, heap slot) and 8 bytes
// per point. Time: each insertion re-scans the samples and edges of the few triangles it
// changes; 1025 x 1025 samples of N44W072 to 1 m: about 4 s of CPU (samples metric, 670k points)
// and 6 s (continuous, 856k points) on one core of the loaded 2-core build machine.
#include "terralod/blocks/greedy_tin.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>

#include "delaunay.hpp"
#include "tin_error.hpp"

namespace terralod::blocks {
namespace {

using detail::next_he;
using detail::prev_he;

using pm::GridPoint;
using pm::orient2d;
/// An edge along the full-resolution grid's diagonal direction (1,1).
bool main_diagonal(GridPoint a, GridPoint b) { return std::int64_t(b.x - a.x) * (b.y - a.y) > 0; }

/// Closed segments p-q and r-s share a point (exact).
bool segments_touch(GridPoint p, GridPoint q, GridPoint r, GridPoint s) {
  const std::int64_t o1 = orient2d(p, q, r), o2 = orient2d(p, q, s), o3 = orient2d(r, s, p),
                     o4 = orient2d(r, s, q);
  auto sgn = [](std::int64_t v) { return (v > 0) - (v < 0); };
  auto on = [](GridPoint a, GridPoint b, GridPoint c) {  // c on segment a-b, given collinear
    return std::min(a.x, b.x) <= c.x && c.x <= std::max(a.x, b.x) && std::min(a.y, b.y) <= c.y &&
           c.y <= std::max(a.y, b.y);
  };
  if (sgn(o1) * sgn(o2) < 0 && sgn(o3) * sgn(o4) < 0) return true;
  return (o1 == 0 && on(p, q, r)) || (o2 == 0 && on(p, q, s)) || (o3 == 0 && on(r, s, p)) ||
         (o4 == 0 && on(r, s, q));
}

class GreedyTin {
 public:
  GreedyTin(const pm::Heightfield& hf, const TinOptions& options, int bx0, int by0, int bx1, int by1)
      : hf_(hf),
        opt_(options),
        linf_(hf, options.metric),
        bx0_(bx0),
        by0_(by0),
        bw_(bx1 - bx0 + 1),
        bh_(by1 - by0 + 1) {
    assert(hf.width() < (1 << 24) && hf.height() < (1 << 24));
    vid_.assign(std::size_t(bw_) * std::size_t(bh_), -1);
    inside_.assign(vid_.size(), 0);
    dt_.on_new_triangle = [this](int) {
      err_.push_back(0.0), serr_.push_back(0.0), cerr_.push_back(0.0), berr_.push_back(0.0);
      cand_.push_back(GridPoint{-1, -1});
      heap_pos_.push_back(-1);
      stuck_.push_back(0);
    };
    // Cocircular ties keep the triangulation Delaunay either way; they are broken towards the
    // (1,1) diagonal, the full-resolution surface's own. This matters for a unit cell whose 4
    // corners are all vertices: its (1,-1) diagonal crosses the grid diagonal between two
    // vertices, an error no insertion could remove.
    dt_.flip_cocircular = [](GridPoint pr, GridPoint pl, GridPoint p0, GridPoint p1) {
      return !main_diagonal(pr, pl) && main_diagonal(p0, p1);
    };
  }

  /// Triangulates the CCW simple ring (ear clipping, then Lawson flips to constrained Delaunay).
  void init(const std::vector<GridPoint>& ring) {
    for (const GridPoint& p : ring) add_point(p);
    const int n = int(ring.size());
    std::vector<int> idx(n);
    for (int i = 0; i < n; ++i) idx[i] = i;
    std::vector<std::array<int, 3>> tris;
    while (idx.size() > 3) {
      const int m = int(idx.size());
      bool clipped = false;
      for (int i = 0; i < m && !clipped; ++i) {
        const int u = idx[(i + m - 1) % m], v = idx[i], w = idx[(i + 1) % m];
        const GridPoint a = pts_[u], b = pts_[v], c = pts_[w];
        if (orient2d(a, b, c) <= 0) continue;
        bool empty = true;
        for (int r : idx) {
          if (r == u || r == v || r == w) continue;
          const GridPoint p = pts_[r];
          if (orient2d(a, b, p) >= 0 && orient2d(b, c, p) >= 0 && orient2d(c, a, p) >= 0) {
            empty = false;
            break;
          }
        }
        if (!empty) continue;
        tris.push_back({u, v, w});
        idx.erase(idx.begin() + i);
        clipped = true;
      }
      if (!clipped)
        throw std::invalid_argument("build_greedy_tin: the polygon could not be triangulated (not simple)");
    }
    if (orient2d(pts_[idx[0]], pts_[idx[1]], pts_[idx[2]]) <= 0)
      throw std::invalid_argument("build_greedy_tin: the polygon is degenerate after rounding to samples");
    tris.push_back({idx[0], idx[1], idx[2]});
    for (const auto& t : tris)
      detail::mark_triangle(pts_[t[0]], pts_[t[1]], pts_[t[2]], bx0_, by0_, bw_, inside_);
    std::unordered_map<std::uint64_t, int> edges;
    for (const auto& t : tris) dt_.set_triangle(dt_.new_triangle(), t[0], t[1], t[2]);
    for (int e = 0; e < int(dt_.tri.size()); ++e) {
      const std::uint64_t a = std::uint32_t(dt_.tri[std::size_t(e)]),
                          b = std::uint32_t(dt_.tri[std::size_t(next_he(e))]);
      auto it = edges.find((b << 32) | a);
      if (it != edges.end())
        dt_.link(e, it->second), edges.erase(it);
      else
        edges.emplace((a << 32) | b, e);
    }
    std::vector<int> stack;
    for (int e = 0; e < int(dt_.tri.size()); ++e)
      if (dt_.half[std::size_t(e)] > e) stack.push_back(e);
    dt_.legalize(stack, /*all_sides=*/true);
    for (int t = 0; t < triangles(); ++t) rescan(t);
  }

  TinSurface run() {
    double first = -1.0;
    std::size_t step = 0;
    while (!heap_.empty() && pts_.size() < opt_.max_points) {
      const int t = heap_[0].t;
      if (err_[t] <= opt_.max_error) break;
      if (first < 0) first = err_[t];
      int at = -1;
      const GridPoint p = choose(t, at);
      if (at < 0) {  // nothing insertable fixes this triangle: it keeps its error
        heap_remove(t);
        stuck_[t] = 1;
        continue;
      }
      insert(p, at);
      if (opt_.progress && (++step & 1023) == 0 && !heap_.empty())
        opt_.progress(progress(first, heap_[0].err));
    }
    TinSurface out;
    out.error = heap_.empty() ? 0.0 : heap_[0].err;
    for (int t = 0; t < triangles(); ++t) {
      if (stuck_[t]) out.error = std::max(out.error, err_[t]);
      out.boundary_error = std::max(out.boundary_error, berr_[t]);
    }
    out.error = std::max(out.error, out.boundary_error);
    out.points.reserve(pts_.size());
    for (const GridPoint& p : pts_) out.points.push_back({p.x, p.y});
    out.triangles.resize(triangles());
    for (int t = 0; t < triangles(); ++t)
      out.triangles[t] = {std::uint32_t(tri_[3 * t]), std::uint32_t(tri_[3 * t + 1]),
                          std::uint32_t(tri_[3 * t + 2])};
    if (opt_.progress) opt_.progress(1.0);
    return out;
  }

 private:
  int triangles() const { return dt_.triangles(); }

  double progress(double first, double now) const {
    double f = pts_.size() >= opt_.max_points ? 1.0 : double(pts_.size()) / double(opt_.max_points);
    if (opt_.max_error > 0 && first > opt_.max_error && now > 0)
      f = std::max(f, std::log(first / now) / std::log(first / opt_.max_error));
    return std::clamp(f, 0.0, 1.0);
  }

  std::int32_t& vid(GridPoint p) { return vid_[std::size_t(p.y - by0_) * bw_ + (p.x - bx0_)]; }
  bool in_box(GridPoint p) const {
    return p.x >= bx0_ && p.x < bx0_ + bw_ && p.y >= by0_ && p.y < by0_ + bh_;
  }

  int add_point(GridPoint p) {
    assert(in_box(p) && vid(p) < 0);
    vid(p) = dt_.add_point(p);
    return vid(p);
  }

  // --- error bookkeeping -------------------------------------------------------------------

  void rescan(int t) {
    const GridPoint a = pts_[tri_[3 * t]], b = pts_[tri_[3 * t + 1]], c = pts_[tri_[3 * t + 2]];
    const detail::SampleScan s = detail::scan_triangle(hf_, a, b, c);
    serr_[t] = s.error;
    cand_[t] = s.worst;
    // Crossings: of interior edges in cerr_ (insertions can fix them), of boundary edges in
    // berr_ (only a sample on the edge can: they count in the error, not in the priority).
    double ce = 0.0, be = 0.0;
    if (opt_.metric == pm::ErrorMetric::Continuous) {
      const GridPoint P[3] = {a, b, c};
      for (int k = 0; k < 3; ++k) {
        const double e = detail::edge_error(linf_, hf_, P[k], P[(k + 1) % 3]);
        if (half_[3 * t + k] >= 0)
          ce = std::max(ce, e);
        else
          be = std::max(be, e);
      }
    }
    cerr_[t] = ce;
    berr_[t] = be;
    err_[t] = std::max(s.error, ce);
    stuck_[t] = 0;
    if (heap_pos_[t] < 0)
      heap_push(t);
    else
      heap_fix(t);
  }

  bool insertable(GridPoint p) {
    return in_box(p) && hf_.valid(p.x, p.y) && vid(p) < 0 &&
           inside_[std::size_t(p.y - by0_) * bw_ + (p.x - bx0_)];
  }

  /// The sample to insert for triangle t and the triangle containing it (at = -1: none).
  GridPoint choose(int t, int& at) {
    at = -1;
    if (cerr_[t] > serr_[t]) {
      detail::Crossing worst;
      for (int k = 0; k < 3; ++k) {
        if (half_[3 * t + k] < 0) continue;
        const detail::Crossing c =
            detail::worst_crossing(hf_, pts_[tri_[3 * t + k]], pts_[tri_[3 * t + (k + 1) % 3]]);
        if (c.s0.x >= 0 && (worst.s0.x < 0 || c.error > worst.error)) worst = c;
      }
      for (GridPoint s : {worst.s0, worst.s1}) {
        if (s.x < 0 || !insertable(s)) continue;
        at = dt_.locate(s, t);
        if (at >= 0) return s;
      }
    }
    if (cand_[t].x >= 0 && insertable(cand_[t])) {
      at = t;
      return cand_[t];
    }
    return GridPoint{-1, -1};
  }

  // --- triangulation updates ---------------------------------------------------------------

  void insert(GridPoint p, int t) {
    dt_.begin_round();
    dt_.insert(add_point(p), t);
    for (int d : dt_.touched) rescan(d);
  }

  // --- indexed max-heap on err_ --------------------------------------------------------------

  void up(int i) {
    const HeapItem item = heap_[i];
    while (i > 0) {
      const int parent = (i - 1) / 2;
      if (!(item.err > heap_[parent].err)) break;
      heap_[i] = heap_[parent], heap_pos_[heap_[i].t] = i, i = parent;
    }
    heap_[i] = item, heap_pos_[item.t] = i;
  }
  void down(int i) {
    const int n = int(heap_.size());
    const HeapItem item = heap_[i];
    for (;;) {
      int m = 2 * i + 1;
      if (m >= n) break;
      if (m + 1 < n && heap_[m + 1].err > heap_[m].err) ++m;
      if (!(heap_[m].err > item.err)) break;
      heap_[i] = heap_[m], heap_pos_[heap_[i].t] = i, i = m;
    }
    heap_[i] = item, heap_pos_[item.t] = i;
  }
  void heap_push(int t) {
    heap_pos_[t] = int(heap_.size());
    heap_.push_back(HeapItem{err_[t], t});
    up(heap_pos_[t]);
  }
  void heap_fix(int t) {
    const int i = heap_pos_[t];
    const double old = heap_[i].err;
    heap_[i].err = err_[t];
    if (err_[t] > old)
      up(i);
    else
      down(i);
  }
  void heap_remove(int t) {
    const int i = heap_pos_[t];
    assert(i >= 0);
    const HeapItem last = heap_.back();
    heap_.pop_back();
    heap_pos_[t] = -1;
    if (last.t == t) return;
    heap_[i] = last, heap_pos_[last.t] = i;
    up(i);
    down(heap_pos_[last.t]);
  }

  const pm::Heightfield& hf_;
  const TinOptions& opt_;
  pm::LInfError linf_;
  int bx0_, by0_, bw_, bh_;
  std::vector<std::int32_t> vid_;
  std::vector<std::uint8_t> inside_;  // samples of the closed domain (1), per sample of the box
  detail::Delaunay dt_;
  std::vector<GridPoint>& pts_ = dt_.pts;
  std::vector<int>& tri_ = dt_.tri;
  std::vector<int>& half_ = dt_.half;
  std::vector<double> err_, serr_, cerr_, berr_;  // priority, samples, interior and boundary crossings
  std::vector<GridPoint> cand_;
  struct HeapItem {
    double err;  // err_[t], kept beside t so that sifting reads contiguous memory
    int t;
  };
  std::vector<HeapItem> heap_;
  std::vector<int> heap_pos_;
  std::vector<std::uint8_t> stuck_;
};

}  // namespace

TinSurface build_greedy_tin(const pm::Heightfield& hf, SampleRect d, const TinOptions& options) {
  assert(d.col0 >= 0 && d.row0 >= 0 && d.col1 < hf.width() && d.row1 < hf.height());
  assert(d.width() >= 2 && d.height() >= 2);
  assert(options.max_error >= 0.0 && options.max_points >= 4);
  GreedyTin tin(hf, options, d.col0, d.row0, d.col1, d.row1);
  // Corners CCW in (col,row): (col0,row0), (col1,row0), (col1,row1), (col0,row1).
  tin.init({{d.col0, d.row0}, {d.col1, d.row0}, {d.col1, d.row1}, {d.col0, d.row1}});
  return tin.run();
}

TinSurface build_greedy_tin(const pm::Heightfield& hf, const std::vector<std::array<double, 2>>& polygon,
                            const TinOptions& options) {
  assert(options.max_error >= 0.0);
  std::vector<GridPoint> ring;
  for (const auto& v : polygon) {
    if (!std::isfinite(v[0]) || !std::isfinite(v[1]))
      throw std::invalid_argument("build_greedy_tin: polygon vertex is not a finite number");
    const double c = std::round(v[0]), r = std::round(v[1]);
    if (c < 0 || r < 0 || c > hf.width() - 1 || r > hf.height() - 1)
      throw std::invalid_argument("build_greedy_tin: polygon vertex (" + std::to_string(v[0]) + ", " +
                                  std::to_string(v[1]) + ") lies outside the " + std::to_string(hf.width()) +
                                  " x " + std::to_string(hf.height()) + " heightfield");
    const GridPoint p{int(c), int(r)};
    if (ring.empty() || !(ring.back() == p)) ring.push_back(p);
  }
  while (ring.size() > 1 && ring.front() == ring.back()) ring.pop_back();
  if (ring.size() < 3)
    throw std::invalid_argument(
        "build_greedy_tin: the polygon has fewer than 3 distinct vertices after rounding");
  std::int64_t area2 = 0;
  for (std::size_t i = 0; i < ring.size(); ++i) {
    const GridPoint a = ring[i], b = ring[(i + 1) % ring.size()];
    area2 += std::int64_t(a.x) * b.y - std::int64_t(b.x) * a.y;
  }
  if (area2 == 0) throw std::invalid_argument("build_greedy_tin: the polygon has zero area after rounding");
  if (area2 < 0) std::reverse(ring.begin(), ring.end());
  const std::size_t n = ring.size();
  for (std::size_t i = 0; i < n; ++i) {
    const GridPoint a = ring[i], b = ring[(i + 1) % n], c = ring[(i + 2) % n];
    // Adjacent edges a-b, b-c may only meet at b: a spike folding back on itself is a crossing.
    if (orient2d(a, b, c) == 0 &&
        (std::int64_t(b.x - a.x) * (c.x - b.x) + std::int64_t(b.y - a.y) * (c.y - b.y)) < 0)
      throw std::invalid_argument("build_greedy_tin: the polygon folds back on itself at vertex (" +
                                  std::to_string(b.x) + ", " + std::to_string(b.y) + ") after rounding");
    for (std::size_t j = i + 2; j < n; ++j) {
      if ((j + 1) % n == i) continue;  // adjacent through the closing edge
      if (segments_touch(a, b, ring[j], ring[(j + 1) % n]))
        throw std::invalid_argument(
            "build_greedy_tin: the polygon is not simple after rounding to samples: edge (" +
            std::to_string(a.x) + "," + std::to_string(a.y) + ")-(" + std::to_string(b.x) + "," +
            std::to_string(b.y) + ") meets edge (" + std::to_string(ring[j].x) + "," +
            std::to_string(ring[j].y) + ")-(" + std::to_string(ring[(j + 1) % n].x) + "," +
            std::to_string(ring[(j + 1) % n].y) + ")");
    }
  }
  assert(options.max_points >= ring.size());
  int x0 = ring[0].x, x1 = x0, y0 = ring[0].y, y1 = y0;
  for (const GridPoint& p : ring)
    x0 = std::min(x0, p.x), x1 = std::max(x1, p.x), y0 = std::min(y0, p.y), y1 = std::max(y1, p.y);
  GreedyTin tin(hf, options, x0, y0, x1, y1);
  tin.init(ring);
  return tin.run();
}

}  // namespace terralod::blocks
