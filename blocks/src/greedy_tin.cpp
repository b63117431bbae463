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

#include "tin_error.hpp"

namespace terralod::blocks {
namespace {

using pm::GridPoint;
using pm::orient2d;
__extension__ typedef __int128 int128;  // GCC/Clang extension, exact for the in-circle test

/// Sign of the in-circle determinant: > 0 when d lies strictly inside the circumcircle of the CCW
/// triangle (a,b,c), 0 when the four are cocircular. Exact: the coordinates are below 2^24, so
/// every product fits in 128 bits.
int in_circle(GridPoint a, GridPoint b, GridPoint c, GridPoint d) {
  const std::int64_t adx = a.x - d.x, ady = a.y - d.y, bdx = b.x - d.x, bdy = b.y - d.y, cdx = c.x - d.x,
                     cdy = c.y - d.y;
  const int128 al = int128(adx * adx + ady * ady), bl = int128(bdx * bdx + bdy * bdy),
               cl = int128(cdx * cdx + cdy * cdy);
  const int128 det = al * int128(bdx * cdy - cdx * bdy) + bl * int128(cdx * ady - adx * cdy) +
                     cl * int128(adx * bdy - bdx * ady);
  return (det > 0) - (det < 0);
}

/// An edge along the full-resolution grid's diagonal direction (1,1).
bool main_diagonal(GridPoint a, GridPoint b) { return std::int64_t(b.x - a.x) * (b.y - a.y) > 0; }

inline int next_he(int e) { return e % 3 == 2 ? e - 2 : e + 1; }
inline int prev_he(int e) { return e % 3 == 0 ? e + 2 : e - 1; }

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
    for (const auto& t : tris) {
      const int id = new_triangle();
      for (int k = 0; k < 3; ++k) tri_[3 * id + k] = t[k];
    }
    for (int e = 0; e < int(tri_.size()); ++e) {
      const std::uint64_t a = std::uint32_t(tri_[e]), b = std::uint32_t(tri_[next_he(e)]);
      auto it = edges.find((b << 32) | a);
      if (it != edges.end())
        link(e, it->second), edges.erase(it);
      else
        edges.emplace((a << 32) | b, e);
    }
    std::vector<int> stack;
    for (int e = 0; e < int(tri_.size()); ++e)
      if (half_[e] > e) stack.push_back(e);
    legalize(stack, /*all_sides=*/true);
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
  int triangles() const { return int(tri_.size() / 3); }

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
    vid(p) = int(pts_.size());
    pts_.push_back(p);
    return int(pts_.size()) - 1;
  }

  int new_triangle() {
    const int t = triangles();
    tri_.insert(tri_.end(), 3, -1);
    half_.insert(half_.end(), 3, -1);
    err_.push_back(0.0), serr_.push_back(0.0), cerr_.push_back(0.0), berr_.push_back(0.0);
    cand_.push_back(GridPoint{-1, -1});
    heap_pos_.push_back(-1);
    stuck_.push_back(0);
    stamp_.push_back(0);
    return t;
  }

  void link(int a, int b) {
    half_[a] = b;
    if (b >= 0) half_[b] = a;
  }

  void set_triangle(int t, int a, int b, int c) {
    tri_[3 * t] = a, tri_[3 * t + 1] = b, tri_[3 * t + 2] = c;
    touch(t);
  }

  void touch(int t) {
    if (stamp_[t] != epoch_) stamp_[t] = epoch_, dirty_.push_back(t);
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
        at = locate(s, t);
        if (at >= 0) return s;
      }
    }
    if (cand_[t].x >= 0 && insertable(cand_[t])) {
      at = t;
      return cand_[t];
    }
    return GridPoint{-1, -1};
  }

  bool contains(int t, GridPoint p) const {
    const GridPoint a = pts_[tri_[3 * t]], b = pts_[tri_[3 * t + 1]], c = pts_[tri_[3 * t + 2]];
    return orient2d(a, b, p) >= 0 && orient2d(b, c, p) >= 0 && orient2d(c, a, p) >= 0;
  }

  /// The triangle whose closed area holds p, by a visibility walk from `start` (a brute-force
  /// search if the walk does not end, which only non-Delaunay triangulations allow); -1 outside.
  int locate(GridPoint p, int start) const {
    int t = start;
    for (int steps = 0; steps < 4096; ++steps) {
      int out = -1;
      for (int k = 0; k < 3 && out < 0; ++k)
        if (orient2d(pts_[tri_[3 * t + k]], pts_[tri_[3 * t + (k + 1) % 3]], p) < 0) out = 3 * t + k;
      if (out < 0) return t;
      if (half_[out] < 0) break;
      t = half_[out] / 3;
    }
    for (int u = 0; u < triangles(); ++u)
      if (contains(u, p)) return u;
    return -1;
  }

  // --- triangulation updates ---------------------------------------------------------------

  void insert(GridPoint p, int t) {
    ++epoch_;
    dirty_.clear();
    const int v = add_point(p);
    const GridPoint P[3] = {pts_[tri_[3 * t]], pts_[tri_[3 * t + 1]], pts_[tri_[3 * t + 2]]};
    int on_edge = -1;
    for (int k = 0; k < 3; ++k)
      if (orient2d(P[k], P[(k + 1) % 3], p) == 0) on_edge = 3 * t + k;
    std::vector<int>& stack = stack_;
    stack.clear();
    if (on_edge < 0) {
      // (a,b,c) -> (a,b,p), (b,c,p), (c,a,p)
      const int a = tri_[3 * t], b = tri_[3 * t + 1], c = tri_[3 * t + 2];
      const int h0 = half_[3 * t], h1 = half_[3 * t + 1], h2 = half_[3 * t + 2];
      const int t1 = new_triangle(), t2 = new_triangle();
      set_triangle(t, a, b, v), set_triangle(t1, b, c, v), set_triangle(t2, c, a, v);
      link(3 * t, h0), link(3 * t1, h1), link(3 * t2, h2);
      link(3 * t + 1, 3 * t1 + 2), link(3 * t1 + 1, 3 * t2 + 2), link(3 * t2 + 1, 3 * t + 2);
      stack = {3 * t, 3 * t1, 3 * t2};
    } else {
      // p on edge a->b of (a,b,c): (a,p,c), (p,b,c); and of the twin (b,a,d): (b,p,d), (p,a,d).
      const int e = on_edge, f = half_[e];
      const int a = tri_[e], b = tri_[next_he(e)], c = tri_[prev_he(e)];
      const int hn = half_[next_he(e)], hp = half_[prev_he(e)];
      const int t1 = new_triangle();
      set_triangle(t, a, v, c), set_triangle(t1, v, b, c);
      link(3 * t + 1, 3 * t1 + 2), link(3 * t + 2, hp), link(3 * t1 + 1, hn);
      stack = {3 * t + 2, 3 * t1 + 1};
      if (f >= 0) {
        const int u = f / 3, d = tri_[prev_he(f)];
        const int ha = half_[next_he(f)], hb = half_[prev_he(f)];
        const int u1 = new_triangle();
        set_triangle(u, b, v, d), set_triangle(u1, v, a, d);
        link(3 * u, 3 * t1), link(3 * u1, 3 * t);
        link(3 * u + 1, 3 * u1 + 2), link(3 * u + 2, hb), link(3 * u1 + 1, ha);
        stack.push_back(3 * u + 2), stack.push_back(3 * u1 + 1);
      } else {
        half_[3 * t] = -1, half_[3 * t1] = -1;
      }
    }
    legalize(stack, /*all_sides=*/false);
    for (int d : dirty_) rescan(d);
  }

  /// Lawson flips of the edges on `stack` (and of the edges their flips expose) until every one
  /// is locally Delaunay; edges without a twin (the boundary) are never flipped. With
  /// all_sides = false the stack holds edges opposite a new point, whose flips expose 2 edges.
  void legalize(std::vector<int>& stack, bool all_sides) {
    while (!stack.empty()) {
      const int e = stack.back();
      stack.pop_back();
      const int f = half_[e];
      if (f < 0) continue;
      const int al = next_he(e), ar = prev_he(e), bl = prev_he(f), br = next_he(f);
      const int p0 = tri_[ar], pr = tri_[e], pl = tri_[al], p1 = tri_[bl];
      // Cocircular ties keep the triangulation Delaunay either way; they are broken towards the
      // (1,1) diagonal, the full-resolution surface's own. This matters for a unit cell whose 4
      // corners are all vertices: its (1,-1) diagonal crosses the grid diagonal between two
      // vertices, an error no insertion could remove.
      const int ic = in_circle(pts_[pr], pts_[pl], pts_[p0], pts_[p1]);
      if (ic < 0 || (ic == 0 && (main_diagonal(pts_[pr], pts_[pl]) || !main_diagonal(pts_[p0], pts_[p1]))))
        continue;
      tri_[e] = p1, tri_[f] = p0;
      const int hbl = half_[bl], har = half_[ar];
      link(e, hbl), link(f, har), link(ar, bl);
      touch(e / 3), touch(f / 3);
      stack.push_back(e), stack.push_back(br);
      if (all_sides) stack.push_back(al), stack.push_back(f);
    }
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
  std::vector<GridPoint> pts_;
  std::vector<int> tri_, half_;
  std::vector<double> err_, serr_, cerr_, berr_;  // priority, samples, interior and boundary crossings
  std::vector<GridPoint> cand_;
  struct HeapItem {
    double err;  // err_[t], kept beside t so that sifting reads contiguous memory
    int t;
  };
  std::vector<HeapItem> heap_;
  std::vector<int> heap_pos_;
  std::vector<std::uint8_t> stuck_;
  std::vector<std::uint32_t> stamp_;
  std::uint32_t epoch_ = 0;
  std::vector<int> dirty_, stack_;
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
