// Private: an incremental Delaunay triangulation on integer points with exact predicates, the
// machinery under the greedy-insertion TIN builders (points are inserted one at a time into the
// triangle that holds them, then Lawson flips restore the Delaunay property).
//
// Representation: triangle t has vertices tri[3t..3t+2] (CCW, indices into pts) and half-edge
// 3t+k runs from tri[3t+k] to tri[3t+(k+1)%3]; half[e] is its twin, -1 on the boundary.
// Boundary edges are never flipped, so a triangulation that starts as a convex polygon's keeps
// that boundary; inserting a point on a boundary edge splits it.
//
// Contract: coordinates below 2^24 in magnitude (orientation in 64-bit, in-circle in 128-bit
// integers, both exact). The owner keeps per-triangle data in step through the on_new_triangle
// hook and learns which triangles changed from `touched` (filled by insert and legalize).
#pragma once

#include <cassert>
#include <cstdint>
#include <functional>
#include <vector>

#include "terralod/pm/linf_error.hpp"

namespace terralod::blocks::detail {

__extension__ typedef __int128 int128;  // GCC/Clang extension, exact for the in-circle test

/// Sign of the in-circle determinant: > 0 when d lies strictly inside the circumcircle of the CCW
/// triangle (a,b,c), 0 when the four are cocircular. Exact for coordinates below 2^24.
inline int in_circle(pm::GridPoint a, pm::GridPoint b, pm::GridPoint c, pm::GridPoint d) {
  const std::int64_t adx = a.x - d.x, ady = a.y - d.y, bdx = b.x - d.x, bdy = b.y - d.y, cdx = c.x - d.x,
                     cdy = c.y - d.y;
  const int128 al = int128(adx * adx + ady * ady), bl = int128(bdx * bdx + bdy * bdy),
               cl = int128(cdx * cdx + cdy * cdy);
  const int128 det = al * int128(bdx * cdy - cdx * bdy) + bl * int128(cdx * ady - adx * cdy) +
                     cl * int128(adx * bdy - bdx * ady);
  return (det > 0) - (det < 0);
}

inline int next_he(int e) { return e % 3 == 2 ? e - 2 : e + 1; }
inline int prev_he(int e) { return e % 3 == 0 ? e + 2 : e - 1; }

class Delaunay {
 public:
  /// Whether to flip the edge pr-pl (shared by triangles (pr,pl,p0) and (pl,pr,p1)) to p0-p1 when
  /// the four points are cocircular; the default keeps it.
  std::function<bool(pm::GridPoint pr, pm::GridPoint pl, pm::GridPoint p0, pm::GridPoint p1)> flip_cocircular;
  /// Called with each new triangle's index, so the owner can grow its per-triangle arrays.
  std::function<void(int)> on_new_triangle;

  std::vector<pm::GridPoint> pts;
  std::vector<int> tri, half;
  /// Triangles created or changed since the owner last cleared it (each once).
  std::vector<int> touched;

  int triangles() const { return int(tri.size() / 3); }
  pm::GridPoint corner(int t, int k) const { return pts[std::size_t(tri[std::size_t(3 * t + k)])]; }

  int add_point(pm::GridPoint p) {
    pts.push_back(p);
    return int(pts.size()) - 1;
  }

  int new_triangle() {
    const int t = triangles();
    tri.insert(tri.end(), 3, -1);
    half.insert(half.end(), 3, -1);
    stamp_.push_back(0);
    if (on_new_triangle) on_new_triangle(t);
    return t;
  }

  void link(int a, int b) {
    half[std::size_t(a)] = b;
    if (b >= 0) half[std::size_t(b)] = a;
  }

  void set_triangle(int t, int a, int b, int c) {
    tri[std::size_t(3 * t)] = a, tri[std::size_t(3 * t + 1)] = b, tri[std::size_t(3 * t + 2)] = c;
    touch(t);
  }

  /// Starts a new round of `touched`.
  void begin_round() {
    ++epoch_;
    touched.clear();
  }

  bool contains(int t, pm::GridPoint p) const {
    const pm::GridPoint a = corner(t, 0), b = corner(t, 1), c = corner(t, 2);
    return pm::orient2d(a, b, p) >= 0 && pm::orient2d(b, c, p) >= 0 && pm::orient2d(c, a, p) >= 0;
  }

  /// The triangle whose closed area holds p, by a visibility walk from `start` (a brute-force
  /// search if the walk does not end, which only non-Delaunay triangulations allow); -1 outside.
  int locate(pm::GridPoint p, int start) const {
    int t = start;
    for (int steps = 0; steps < 4096; ++steps) {
      int out = -1;
      for (int k = 0; k < 3 && out < 0; ++k)
        if (pm::orient2d(corner(t, k), corner(t, (k + 1) % 3), p) < 0) out = 3 * t + k;
      if (out < 0) return t;
      if (half[std::size_t(out)] < 0) break;
      t = half[std::size_t(out)] / 3;
    }
    for (int u = 0; u < triangles(); ++u)
      if (contains(u, p)) return u;
    return -1;
  }

  /// Inserts point v (already in pts) into triangle t, whose closed area holds it and none of
  /// whose corners it equals, and legalizes. Triangles changed go to `touched`.
  void insert(int v, int t) {
    const pm::GridPoint p = pts[std::size_t(v)];
    int on_edge = -1;
    for (int k = 0; k < 3; ++k)
      if (pm::orient2d(corner(t, k), corner(t, (k + 1) % 3), p) == 0) on_edge = 3 * t + k;
    std::vector<int>& stack = stack_;
    stack.clear();
    if (on_edge < 0) {
      // (a,b,c) -> (a,b,p), (b,c,p), (c,a,p)
      const int a = tri[std::size_t(3 * t)], b = tri[std::size_t(3 * t + 1)], c = tri[std::size_t(3 * t + 2)];
      const int h0 = half[std::size_t(3 * t)], h1 = half[std::size_t(3 * t + 1)],
                h2 = half[std::size_t(3 * t + 2)];
      const int t1 = new_triangle(), t2 = new_triangle();
      set_triangle(t, a, b, v), set_triangle(t1, b, c, v), set_triangle(t2, c, a, v);
      link(3 * t, h0), link(3 * t1, h1), link(3 * t2, h2);
      link(3 * t + 1, 3 * t1 + 2), link(3 * t1 + 1, 3 * t2 + 2), link(3 * t2 + 1, 3 * t + 2);
      stack = {3 * t, 3 * t1, 3 * t2};
    } else {
      // p on edge a->b of (a,b,c): (a,p,c), (p,b,c); and of the twin (b,a,d): (b,p,d), (p,a,d).
      const int e = on_edge, f = half[std::size_t(e)];
      const int a = tri[std::size_t(e)], b = tri[std::size_t(next_he(e))], c = tri[std::size_t(prev_he(e))];
      const int hn = half[std::size_t(next_he(e))], hp = half[std::size_t(prev_he(e))];
      const int t1 = new_triangle();
      set_triangle(t, a, v, c), set_triangle(t1, v, b, c);
      link(3 * t + 1, 3 * t1 + 2), link(3 * t + 2, hp), link(3 * t1 + 1, hn);
      stack = {3 * t + 2, 3 * t1 + 1};
      if (f >= 0) {
        const int u = f / 3, d = tri[std::size_t(prev_he(f))];
        const int ha = half[std::size_t(next_he(f))], hb = half[std::size_t(prev_he(f))];
        const int u1 = new_triangle();
        set_triangle(u, b, v, d), set_triangle(u1, v, a, d);
        link(3 * u, 3 * t1), link(3 * u1, 3 * t);
        link(3 * u + 1, 3 * u1 + 2), link(3 * u + 2, hb), link(3 * u1 + 1, ha);
        stack.push_back(3 * u + 2), stack.push_back(3 * u1 + 1);
      } else {
        half[std::size_t(3 * t)] = -1, half[std::size_t(3 * t1)] = -1;
      }
    }
    legalize(stack, /*all_sides=*/false);
  }

  /// Lawson flips of the edges on `stack` (and of the edges their flips expose) until every one
  /// is locally Delaunay; edges without a twin (the boundary) are never flipped. With
  /// all_sides = false the stack holds edges opposite a new point, whose flips expose 2 edges.
  void legalize(std::vector<int>& stack, bool all_sides) {
    while (!stack.empty()) {
      const int e = stack.back();
      stack.pop_back();
      const int f = half[std::size_t(e)];
      if (f < 0) continue;
      const int al = next_he(e), ar = prev_he(e), bl = prev_he(f), br = next_he(f);
      const int p0 = tri[std::size_t(ar)], pr = tri[std::size_t(e)], pl = tri[std::size_t(al)],
                p1 = tri[std::size_t(bl)];
      const pm::GridPoint P0 = pts[std::size_t(p0)], PR = pts[std::size_t(pr)], PL = pts[std::size_t(pl)],
                          P1 = pts[std::size_t(p1)];
      const int ic = in_circle(PR, PL, P0, P1);
      if (ic < 0 || (ic == 0 && !(flip_cocircular && flip_cocircular(PR, PL, P0, P1)))) continue;
      tri[std::size_t(e)] = p1, tri[std::size_t(f)] = p0;
      const int hbl = half[std::size_t(bl)], har = half[std::size_t(ar)];
      link(e, hbl), link(f, har), link(ar, bl);
      touch(e / 3), touch(f / 3);
      stack.push_back(e), stack.push_back(br);
      if (all_sides) stack.push_back(al), stack.push_back(f);
    }
  }

 private:
  void touch(int t) {
    if (stamp_[std::size_t(t)] != epoch_) stamp_[std::size_t(t)] = epoch_, touched.push_back(t);
  }

  std::vector<std::uint32_t> stamp_;
  std::uint32_t epoch_ = 1;
  std::vector<int> stack_;
};

}  // namespace terralod::blocks::detail
