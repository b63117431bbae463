// L-infinity meshes of geographic tiles with shared edge vertices (see tile_mesher.hpp).
#include "tile_mesher.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <queue>
#include <unordered_set>
#include <utility>

#include "../delaunay.hpp"

namespace terralod::blocks::detail {
namespace {

constexpr int kQ = 32767;            // largest quantized coordinate
constexpr int kBackgroundGrid = 64;  // background points: (kBackgroundGrid + 1)^2 per tile
constexpr double kEps = 1e-9;        // lattice steps: points on a triangle's edge count in both

/// The tile's quantized frame: lattice point (c, r) sits at u = u0 + c du, v = v0 - r dv.
struct TileFrame {
  TileFrame(const GeoGrid& g, const GeoRect& rect)
      : ku(kQ / (rect.east - rect.west)),
        kv(kQ / (rect.north - rect.south)),
        u0((g.west - rect.west) * ku),
        du(g.dlon * ku),
        v0((g.north - rect.south) * kv),
        dv(g.dlat * kv) {}
  double ku, kv, u0, du, v0, dv;
  double u(int c) const { return u0 + c * du; }
  double v(int r) const { return v0 - r * dv; }
};

struct UV {
  double u, v;
};

/// Calls span(r, v, ul, ur) for every row r of the padded grid (GeoField::kPad rings) that the
/// closed triangle (a, b, c) crosses (within kEps lattice steps): v is the row's coordinate and
/// [ul, ur] the triangle's extent along it.
template <class F>
void for_each_row_span(const TileFrame& fr, int height, const UV (&p)[3], F&& span) {
  const double vmin = std::min({p[0].v, p[1].v, p[2].v}), vmax = std::max({p[0].v, p[1].v, p[2].v});
  constexpr int pad = GeoField::kPad;
  const int r_lo = std::max(-pad, int(std::ceil((fr.v0 - vmax) / fr.dv - kEps)));
  const int r_hi = std::min(height - 1 + pad, int(std::floor((fr.v0 - vmin) / fr.dv + kEps)));
  for (int r = r_lo; r <= r_hi; ++r) {
    const double v = fr.v(r);
    double ul = std::numeric_limits<double>::infinity(), ur = -ul;
    for (int k = 0; k < 3; ++k) {
      const UV& a = p[k];
      const UV& b = p[(k + 1) % 3];
      if (a.v == b.v) {
        if (std::abs(a.v - v) <= kEps * fr.dv) ul = std::min({ul, a.u, b.u}), ur = std::max({ur, a.u, b.u});
        continue;
      }
      const double lo = std::min(a.v, b.v) - kEps * fr.dv, hi = std::max(a.v, b.v) + kEps * fr.dv;
      if (v < lo || v > hi) continue;
      const double t = std::clamp((v - a.v) / (b.v - a.v), 0.0, 1.0);
      const double u = a.u + t * (b.u - a.u);
      ul = std::min(ul, u), ur = std::max(ur, u);
    }
    if (ul <= ur) span(r, v, ul, ur);
  }
}

/// Calls row(r, c_lo, c_hi, v) for every row r of the padded grid (GeoField::kPad rings) whose
/// lattice points c_lo..c_hi (c_lo <= c_hi) lie in the closed triangle (a, b, c) (and, within
/// kEps lattice steps, on its edges); v is the row's coordinate.
template <class F>
void scan_lattice_rows(const TileFrame& fr, int width, int height, const UV (&p)[3], F&& row) {
  constexpr int pad = GeoField::kPad;
  for_each_row_span(fr, height, p, [&](int r, double v, double ul, double ur) {
    const int c_lo = std::max(-pad, int(std::ceil((ul - fr.u0) / fr.du - kEps)));
    const int c_hi = std::min(width - 1 + pad, int(std::floor((ur - fr.u0) / fr.du + kEps)));
    if (c_lo <= c_hi) row(r, c_lo, c_hi, v);
  });
}

/// Where a lattice's columns lie more than two of its rows apart in the tile's quanta (a grid of
/// cells square on the ground far from the equator: six rows at 80 degrees, seventy near a pole),
/// points between them keep what is measured along its rows as dense as that: f(c, r, u, v, z)
/// for every point at column c + k / n (k = 1 .. n - 1, n = ceil(du / 2 dv)) on a row r in the
/// closed triangle where lattice points c and c + 1 are not holes; z is the field there, linear
/// between them. Measuring only the
/// lattice, a tile narrower than a column held no measured point at all, and its triangles
/// joined the terrain to the background's foot across the samples nearest it (155 m off around
/// the South Pole).
template <class F>
void scan_row_points(const GeoField& field, const TileFrame& fr, const UV (&p)[3], F&& f) {
  const int n = int(std::ceil(fr.du / (2.0 * fr.dv) - kEps));
  if (n < 2) return;
  constexpr int pad = GeoField::kPad;
  const int width = field.grid().width;
  for_each_row_span(fr, field.grid().height, p, [&](int r, double v, double ul, double ur) {
    const long lo = std::max(long(-pad) * n, long(std::ceil((ul - fr.u0) / fr.du * n - kEps)));
    const long hi = std::min(long(width - 1 + pad) * n, long(std::floor((ur - fr.u0) / fr.du * n + kEps)));
    for (long s = lo; s <= hi; ++s) {
      const long c = s >= 0 ? s / n : -((-s + n - 1) / n);
      if (s == c * n) continue;  // a lattice point
      const double z0 = field.lattice(int(c), r), z1 = field.lattice(int(c) + 1, r);
      if (z0 != z0 || z1 != z1) continue;  // beside a hole: not measured
      const double x = double(s - c * n) / n;
      f(int(c), r, fr.u0 + (double(c) + x) * fr.du, v, z0 + x * (z1 - z0));
    }
  });
}

/// Calls f(c, r, u, v) for every lattice point scan_lattice_rows finds.
template <class F>
void scan_lattice(const TileFrame& fr, int width, int height, const UV (&p)[3], F&& f) {
  scan_lattice_rows(fr, width, height, p, [&](int r, int c_lo, int c_hi, double v) {
    for (int c = c_lo; c <= c_hi; ++c) f(c, r, fr.u(c), v);
  });
}

/// The plane through three (u, v, h) points: h(u, v) = h0 + gx (u - u0) + gy (v - v0).
struct Plane {
  Plane(const UV (&p)[3], const double (&h)[3]) : u0(p[0].u), v0(p[0].v), h0(h[0]) {
    const double au = p[1].u - p[0].u, av = p[1].v - p[0].v, bu = p[2].u - p[0].u, bv = p[2].v - p[0].v;
    const double det = au * bv - bu * av;
    gx = ((h[1] - h[0]) * bv - (h[2] - h[0]) * av) / det;
    gy = ((h[2] - h[0]) * au - (h[1] - h[0]) * bu) / det;
  }
  double operator()(double u, double v) const { return h0 + gx * (u - u0) + gy * (v - v0); }
  double u0, v0, h0, gx = 0, gy = 0;
};

bool in_closed_triangle(const UV (&p)[3], double u, double v) {
  auto side = [&](const UV& a, const UV& b) { return (b.u - a.u) * (v - a.v) - (b.v - a.v) * (u - a.u); };
  const double tol = 1e-9 * kQ;
  return side(p[0], p[1]) >= -tol && side(p[1], p[2]) >= -tol && side(p[2], p[0]) >= -tol;
}

/// Background points of a tile: the (kBackgroundGrid + 1)^2 regular grid, less the points within
/// one lattice step of the padded grid (the rings measure the terrain's own edge). A triangle
/// visits the points of its bounding box only, through the grid's indices: a tile at the
/// terrain's edge keeps thousands of them, and reading them all for every rescanned triangle
/// made a large tile's greedy quadratic (a 513^2 terrain exported with --max-level 4, where
/// its two tiles of 11 degrees hold every sample at 1 m: 2.1x the time).
class BackgroundPoints {
 public:
  BackgroundPoints(const GeoGrid& g, const TileFrame& fr)
      : ulo_(fr.u(-kRing)),
        uhi_(fr.u(g.width - 1 + kRing)),
        vlo_(fr.v(g.height - 1 + kRing)),
        vhi_(fr.v(-kRing)) {}
  BackgroundPoints() : empty_(true) {}

  /// Calls f(p) for every point of the box [ulo, uhi] x [vlo, vhi], row by row from the south, and
  /// for some points just outside it (callers test the box or the triangle themselves).
  template <class F>
  void for_each(double ulo, double uhi, double vlo, double vhi, F&& f) const {
    // A box within the padded grid holds no point (those just outside it, which the callers
    // reject, are not needed): most triangles of a tile over the terrain. Their 3 x 3 or more
    // grid indices were a seventh of the greedy's rescans.
    if (empty_ || (ulo >= ulo_ && uhi <= uhi_ && vlo >= vlo_ && vhi <= vhi_)) return;
    const int i0 = index(ulo, -1), i1 = index(uhi, 1), j0 = index(vlo, -1), j1 = index(vhi, 1);
    for (int j = j0; j <= j1; ++j)
      for (int i = i0; i <= i1; ++i) {
        const UV p{double(i) * kQ / kBackgroundGrid, double(j) * kQ / kBackgroundGrid};
        if (p.u >= ulo_ && p.u <= uhi_ && p.v >= vlo_ && p.v <= vhi_) continue;
        f(p);
      }
  }

 private:
  static constexpr int kRing = GeoField::kPad + 1;
  /// The grid index of the quantized coordinate x, one beyond it towards `side` (rounding).
  static int index(double x, int side) {
    const double k = std::clamp(x, 0.0, double(kQ)) * kBackgroundGrid / kQ;
    return std::clamp(int(side < 0 ? std::floor(k) : std::ceil(k)) + side, 0, kBackgroundGrid);
  }
  double ulo_ = 0, uhi_ = 0, vlo_ = 0, vhi_ = 0;
  bool empty_ = false;
};

struct EdgePoint {
  double t, h;
  bool forced;
};

/// The vertices of one tile edge: (quantized position along the edge, height), from both ends.
/// vertical: the edge lies on longitude `at` from latitude a to b; else on latitude `at` from
/// longitude a to b. A function of its arguments only (see the header).
std::vector<std::pair<int, double>> edge_vertices(const GeoField& f, bool vertical, double at, double a,
                                                  double b, double tol, int divisions) {
  const GeoGrid& g = f.grid();
  std::vector<EdgePoint> pts;
  auto corner = [&](double s) { return vertical ? f.at(at, s) : f.at(s, at); };
  pts.push_back({0.0, corner(a), true});
  pts.push_back({1.0, corner(b), true});
  for (int k = 1; k < divisions; ++k) {
    const double s = a + (b - a) * k / divisions;
    if (!(vertical ? f.at_terrain_edge(at, s) : f.at_terrain_edge(s, at)))
      pts.push_back({double(k) / divisions, corner(s), true});
  }
  // Crossings with lattice lines (only where the padded lattice is: beyond it the field is flat).
  constexpr int pad = GeoField::kPad;
  const double lo = std::min(a, b), hi = std::max(a, b);
  if (vertical) {
    if (at >= g.lon(-pad) && at <= g.lon(g.width - 1 + pad))
      for (int r = -pad; r <= g.height - 1 + pad; ++r) {
        const double lat = g.lat(r);
        if (lat > lo && lat < hi) pts.push_back({(lat - a) / (b - a), f.on_row(at, r), false});
      }
  } else {
    if (at <= g.lat(-pad) && at >= g.lat(g.height - 1 + pad))
      for (int c = -pad; c <= g.width - 1 + pad; ++c) {
        const double lon = g.lon(c);
        if (lon > lo && lon < hi) pts.push_back({(lon - a) / (b - a), f.on_col(c, at), false});
      }
  }
  std::sort(pts.begin(), pts.end(), [](const EdgePoint& x, const EdgePoint& y) { return x.t < y.t; });
  // Douglas-Peucker between consecutive forced points.
  std::vector<std::uint8_t> keep(pts.size(), 0);
  std::vector<std::pair<std::size_t, std::size_t>> stack;
  std::size_t prev = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    if (!pts[i].forced) continue;
    keep[i] = 1;
    if (i > prev + 1) stack.push_back({prev, i});
    prev = i;
  }
  while (!stack.empty()) {
    const auto [i, j] = stack.back();
    stack.pop_back();
    double worst = tol;
    std::size_t at_k = 0;
    for (std::size_t k = i + 1; k < j; ++k) {
      const double s = (pts[k].t - pts[i].t) / (pts[j].t - pts[i].t);
      const double e = std::abs(pts[i].h + s * (pts[j].h - pts[i].h) - pts[k].h);
      if (e > worst) worst = e, at_k = k;
    }
    if (at_k == 0) continue;
    keep[at_k] = 1;
    if (at_k > i + 1) stack.push_back({i, at_k});
    if (j > at_k + 1) stack.push_back({at_k, j});
  }
  std::vector<std::pair<int, double>> out;
  std::vector<double> exact;  // out[k]'s position before rounding, in quanta
  for (std::size_t i = 0; i < pts.size(); ++i) {
    if (!keep[i]) continue;
    const int q = int(std::lround(pts[i].t * kQ));
    if (!out.empty() && out.back().first == q) {
      if (q == kQ) {  // the end wins its position
        out.back().second = pts[i].h;
        exact.back() = pts[i].t * kQ;
      }
      continue;
    }
    out.push_back({q, pts[i].h});
    exact.push_back(pts[i].t * kQ);
  }
  // Rounding moves a vertex along the edge by up to half a quantum, and beside a cliff that
  // alone errs at the vertex's own sample: the foot of a 5,400 m cliff 622 quanta wide, rounded
  // 0.485 quanta towards it, was drawn 4.2 m high at its sample at a 1 m level (the 0 m border
  // test of test_terrain_export). Such a vertex gets a twin of its height on the quantum at the
  // other side of its true position, so that the edge is flat through it. Twins of neighbours
  // that land on one quantum are one vertex (the first; build_initial skips the second), for
  // both tiles alike: a function of the edge alone still, as the tiles that share it need.
  std::vector<std::pair<int, double>> bracketed;
  bracketed.reserve(out.size());
  for (std::size_t k = 0; k < out.size(); ++k) {
    bracketed.push_back(out[k]);
    const double d = exact[k] - out[k].first;  // where the vertex belongs, from where it is
    if (k == 0 || k + 1 == out.size() || d == 0.0) continue;
    const std::size_t n = d > 0 ? k + 1 : k - 1;  // the neighbour on the side of the true position
    const double drawn =
        out[k].second + (out[n].second - out[k].second) * std::abs(d) / std::abs(out[n].first - out[k].first);
    const int twin = out[k].first + (d > 0 ? 1 : -1);
    if (std::abs(drawn - out[k].second) <= tol / 16 || twin == out[n].first) continue;
    if (d > 0) {
      bracketed.push_back({twin, out[k].second});
    } else {
      bracketed.insert(bracketed.end() - 1, {twin, out[k].second});
    }
  }
  return bracketed;
}

class TileGreedy {
 public:
  TileGreedy(const GeoField& f, const GeoRect& rect, const TileMeshOptions& o)
      : f_(f), g_(f.grid()), rect_(rect), opt_(o), fr_(f.grid(), rect), background_(g_, fr_) {
    dt_.on_new_triangle = [this](int) {
      prio_.push_back(0), all_.push_back(0), version_.push_back(0);
      cand_.push_back({0, 0}), cand_h_.push_back(0);
    };
  }

  TileMesh run() {
    build_initial();
    for (int t = 0; t < dt_.triangles(); ++t) rescan(t);
    TileMesh out;
    while (!heap_.empty()) {
      const Item top = heap_.top();
      if (top.version != version_[std::size_t(top.t)]) {
        heap_.pop();
        continue;
      }
      if (top.err <= opt_.max_error) break;
      heap_.pop();
      const int t = top.t;
      const UV& c = cand_[std::size_t(t)];
      pm::GridPoint p = rounded(c);
      int at = dt_.locate(p, t);
      const bool elsewhere = at >= 0 && has_corner(at, p);
      // On a coarse lattice, only a point that breaks the level's bound (edge_error is a little
      // below it) takes another corner (see fine_lattice_).
      if (elsewhere) at = fine_lattice_ || top.err > opt_.edge_error ? free_corner(c, p, at) : -1;
      if (at < 0) {  // outside, or every lattice position around the point is a vertex already
        // The point stays stuck (measured, never a candidate again), and t's next worst point
        // becomes t's candidate. Dropping t left its other points as they were: under a sliver
        // from a tile edge across a cliff top, 0 m samples stayed 5,000 m off.
        stuck_.insert(std::uint32_t(p.x) << 16 | std::uint32_t(p.y));
        ++out.stuck;
        rescan(t);
        continue;
      }
      add_vertex(p, cand_h_[std::size_t(t)], at);
      for (int d : dt_.touched) rescan(d);
      // The vertex may lie outside t (the point's rounded position, or another corner of its
      // cell, across an edge from it) and leave t as it was: t is then looked at again, as its
      // entry was popped, until the point's corners bracket it or it is stuck.
      if (std::find(dt_.touched.begin(), dt_.touched.end(), t) == dt_.touched.end()) rescan(t);
    }
    for (int t = 0; t < dt_.triangles(); ++t) out.error = std::max(out.error, all_[std::size_t(t)]);
    out.uv.reserve(dt_.pts.size());
    for (const pm::GridPoint& p : dt_.pts) out.uv.push_back({p.x, p.y});
    out.heights = h_;
    out.triangles.resize(std::size_t(dt_.triangles()));
    for (int t = 0; t < dt_.triangles(); ++t)
      out.triangles[std::size_t(t)] = {std::uint32_t(dt_.tri[std::size_t(3 * t)]),
                                       std::uint32_t(dt_.tri[std::size_t(3 * t + 1)]),
                                       std::uint32_t(dt_.tri[std::size_t(3 * t + 2)])};
    return out;
  }

 private:
  /// Whether p is a corner of triangle t: of the triangle locate() finds for p, exactly when p is
  /// a vertex already (every triangle around a vertex holds it). A hash set of the vertices
  /// answered this before, at 12 % of a large tile's time and about 40 bytes a vertex.
  bool has_corner(int t, pm::GridPoint p) const {
    for (int k = 0; k < 3; ++k)
      if (dt_.corner(t, k) == p) return true;
    return false;
  }

  /// Whether points rounded to p were found stuck (run()). Asked only of a point about to become
  /// its triangle's candidate, and the set is empty on most tiles.
  bool is_stuck(pm::GridPoint p) const {
    return !stuck_.empty() && stuck_.count(std::uint32_t(p.x) << 16 | std::uint32_t(p.y)) != 0;
  }

  /// Where a point at (u, v) is inserted: the nearest lattice position.
  static pm::GridPoint rounded(const UV& q) { return {int(std::lround(q.u)), int(std::lround(q.v))}; }

  /// A point whose rounded position p is a vertex already, and yet is measured above max_error
  /// (on a lattice much finer than the samples, fine_lattice_): the corners of the quantum cell
  /// around its true position (u, v), nearest first, are where else it can go, with its own
  /// height. Each one more brackets the point: once the cell's corners are vertices at its
  /// height, the mesh passes through it exactly. Rounding bites at the top of a cliff: a sample
  /// at 5,000 m beside the 0 m a warp writes outside a projected DEM, rounded a third of a
  /// quantum towards a cliff 600 quanta wide, erred by 3.5 m at its vertex's own height. Sets p
  /// and returns the triangle holding it; -1 when every corner inside the tile is a vertex.
  int free_corner(const UV& at_uv, pm::GridPoint& p, int from) const {
    const double u0 = std::floor(at_uv.u), v0 = std::floor(at_uv.v);
    std::array<pm::GridPoint, 4> corners;
    for (int k = 0; k < 4; ++k) corners[std::size_t(k)] = {int(u0) + (k & 1), int(v0) + (k >> 1)};
    const auto d2 = [&](pm::GridPoint q) {
      const double du = q.x - at_uv.u, dv = q.y - at_uv.v;
      return du * du + dv * dv;
    };
    std::sort(corners.begin(), corners.end(),
              [&](pm::GridPoint a, pm::GridPoint b) { return d2(a) < d2(b); });
    for (const pm::GridPoint q : corners) {
      if (q.x <= 0 || q.x >= kQ || q.y <= 0 || q.y >= kQ) continue;
      const int t = dt_.locate(q, from);
      if (t >= 0 && !has_corner(t, q)) {
        p = q;
        return t;
      }
    }
    return -1;
  }

  void add_vertex(pm::GridPoint p, double h, int t) {
    const int v = dt_.add_point(p);
    h_.push_back(h);
    dt_.begin_round();
    dt_.insert(v, t);
  }

  /// Corners, edge vertices and the forced interior grid.
  void build_initial() {
    const GeoRect& r = rect_;
    const std::array<pm::GridPoint, 4> corners = {{{0, 0}, {kQ, 0}, {kQ, kQ}, {0, kQ}}};
    const std::array<double, 4> ch = {f_.at(r.west, r.south), f_.at(r.east, r.south), f_.at(r.east, r.north),
                                      f_.at(r.west, r.north)};
    for (int k = 0; k < 4; ++k) {
      dt_.add_point(corners[std::size_t(k)]);
      h_.push_back(ch[std::size_t(k)]);
    }
    const int t0 = dt_.new_triangle(), t1 = dt_.new_triangle();
    dt_.set_triangle(t0, 0, 1, 2), dt_.set_triangle(t1, 0, 2, 3);
    dt_.link(3 * t0 + 2, 3 * t1);
    const double tol = opt_.edge_error;
    const int n = std::max(1, opt_.sag_divisions);
    // Each point's walk starts where the previous point went: in a triangle that point's
    // insertion touched when one holds the new point, else in the triangle that took it. An edge's
    // points come in order along it, so each lies on the boundary segment between the previous
    // one and the edge's far end (found at once), and the forced grid's come row by row. From
    // triangle 0, a tile of 11 degrees at 1 m (forced points every few km, thousands of edge
    // vertices) walked 0.49 M times, 710 triangles a walk. A point on an edge of two triangles
    // may go into either, as the start decides; the triangulation stays Delaunay (where points
    // are cocircular it may differ, as a different insertion order's would).
    int last = 0;
    auto add = [&](pm::GridPoint p, double h) {
      int start = last;
      for (int t : dt_.touched)
        if (dt_.contains(t, p)) {
          start = t;
          break;
        }
      const int at = dt_.locate(p, start);
      if (at < 0 || has_corner(at, p)) return;  // (every point lies in the tile: never outside)
      add_vertex(p, h, last = at);
    };
    // Along a parallel, forced points as far apart on the ground as along a meridian: n times
    // the cosine of the latitude (for a row, of the one nearest the equator among the rows beside
    // it), a function of the latitude alone, so that the two tiles of a south or north edge
    // agree. (n on every parallel put them metres apart near a pole: a 5 km DEM around the South
    // Pole exported 5.07 M vertices at its deepest level for 493 k samples.)
    const auto along = [n](double lat_lo, double lat_hi) {
      const double nearest =
          lat_lo <= 0.0 && lat_hi >= 0.0 ? 0.0 : std::min(std::abs(lat_lo), std::abs(lat_hi));
      return std::clamp(int(std::ceil(n * std::cos(nearest * std::numbers::pi / 180.0) - 1e-9)), 1, n);
    };
    const auto lat_of = [&](int j) { return r.south + (r.north - r.south) * j / n; };
    // West and east edges run south -> north, south and north edges west -> east.
    for (const auto& [q, h] : edge_vertices(f_, true, r.west, r.south, r.north, tol, n)) add({0, q}, h);
    for (const auto& [q, h] : edge_vertices(f_, true, r.east, r.south, r.north, tol, n)) add({kQ, q}, h);
    for (const auto& [q, h] : edge_vertices(f_, false, r.south, r.west, r.east, tol, along(r.south, r.south)))
      add({q, 0}, h);
    for (const auto& [q, h] : edge_vertices(f_, false, r.north, r.west, r.east, tol, along(r.north, r.north)))
      add({q, kQ}, h);
    for (int j = 1; j < n; ++j) {
      const int m = along(lat_of(j - 1), lat_of(j + 1));
      for (int i = 1; i < m; ++i) {
        const double lon = r.west + (r.east - r.west) * i / m, lat = lat_of(j);
        if (!f_.at_terrain_edge(lon, lat))
          add({int(std::lround(double(i) / m * kQ)), int(std::lround(double(j) / n * kQ))}, f_.at(lon, lat));
      }
    }
  }

  void corners(int t, UV (&p)[3], double (&h)[3]) const {
    for (int k = 0; k < 3; ++k) {
      const int v = dt_.tri[std::size_t(3 * t + k)];
      const pm::GridPoint q = dt_.pts[std::size_t(v)];
      p[k] = {double(q.x), double(q.y)};
      h[k] = h_[std::size_t(v)];
    }
  }

  void rescan(int t) {
    UV p[3];
    double h[3];
    corners(t, p, h);
    const Plane plane(p, h);
    double all = 0, best = 0;
    bool found = false;
    UV cand{0, 0};
    double cand_h = 0;
    auto consider = [&](double u, double v, double value) {
      const double e = std::abs(plane(u, v) - value);
      all = std::max(all, e);
      if (e <= best) return;
      const pm::GridPoint q = rounded({u, v});
      if (q.x <= 0 || q.x >= kQ || q.y <= 0 || q.y >= kQ || is_stuck(q)) return;
      best = e, found = true, cand = {u, v}, cand_h = value;
    };
    // The lattice points, GeoField::lattice's values: the grid's own samples read straight from
    // its rows (the lattice's bounds and ring tests were a third of the greedy's rescans).
    const int w = g_.width, hgt = g_.height;
    scan_lattice_rows(fr_, w, hgt, p, [&](int r, int c_lo, int c_hi, double v) {
      const auto ring = [&](int c) {
        const double value = f_.lattice(c, r);
        if (value == value) consider(fr_.u(c), v, value);
      };
      int c = c_lo;
      if (r >= 0 && r < hgt) {
        const int last = std::min(c_hi, w - 1);
        for (; c <= c_hi && c < 0; ++c) ring(c);
        const std::size_t row = std::size_t(r) * std::size_t(w);
        const float* z = g_.heights.data() + row;
        const std::uint8_t* valid = g_.mask.empty() ? nullptr : g_.mask.data() + row;
        for (; c <= last; ++c)
          if ((!valid || valid[c] != 0) && z[c] == z[c]) consider(fr_.u(c), v, z[c]);
      }
      for (; c <= c_hi; ++c) ring(c);
    });
    scan_row_points(f_, fr_, p, [&](int, int, double u, double v, double z) { consider(u, v, z); });
    const double ulo = std::min({p[0].u, p[1].u, p[2].u}), uhi = std::max({p[0].u, p[1].u, p[2].u});
    const double vlo = std::min({p[0].v, p[1].v, p[2].v}), vhi = std::max({p[0].v, p[1].v, p[2].v});
    background_.for_each(ulo, uhi, vlo, vhi, [&](const UV& b) {
      if (b.u >= ulo && b.u <= uhi && b.v >= vlo && b.v <= vhi && in_closed_triangle(p, b.u, b.v))
        consider(b.u, b.v, f_.background());
    });
    const std::size_t i = std::size_t(t);
    all_[i] = all, prio_[i] = best, cand_[i] = cand, cand_h_[i] = cand_h;
    ++version_[i];
    if (found) heap_.push({best, t, version_[i]});
  }

  const GeoField& f_;
  const GeoGrid& g_;
  GeoRect rect_;
  TileMeshOptions opt_;
  TileFrame fr_;
  // At least 16 quanta between lattice points each way (natural depths have 512 or more): a
  // point's cell is then its own, and rounding is off by 1/32 of the spacing at most, which only
  // cliffs turn into errors (free_corner). On coarser lattices, a deepest level far shallower
  // than the natural one, rounding errs at most samples of rough terrain: their corners
  // quadrupled the vertices (a 2401^2 mosaic at --max-level 4, 2.4 quanta apart: over 8 minutes
  // instead of 3.4), so there only points above the level's bound take corners. N44W072 at
  // --max-level 5 (4.8 quanta apart, 1 m): 55.5 m -> 3.8 m measured, 1.36x the vertices, 1.44x
  // the time; at the coarse levels of the natural depth, cliff tops (see run()).
  bool fine_lattice_ = fr_.du >= 16 && fr_.dv >= 16;
  std::unordered_set<std::uint32_t> stuck_;
  BackgroundPoints background_;
  Delaunay dt_;
  std::vector<double> h_;
  std::vector<double> prio_, all_, cand_h_;
  std::vector<UV> cand_;  // a triangle's worst point, where it lies (inserted at rounded())
  std::vector<std::uint32_t> version_;
  struct Item {
    double err;
    int t;
    std::uint32_t version;
    bool operator<(const Item& o) const { return err < o.err || (err == o.err && t > o.t); }
  };
  std::priority_queue<Item> heap_;
};

}  // namespace

GeoField::GeoField(const GeoGrid& grid, double background)
    : g_(grid), background_(background), period_(grid.period()) {
  const auto pole_value = [&](int r, double pole) {
    const double gap = std::abs(pole - grid.lat(r));
    if (period_ == 0 || gap == 0.0 || gap > grid.dlat) return std::numeric_limits<double>::quiet_NaN();
    double sum = 0.0;
    int n = 0;
    for (int c = 0; c < period_; ++c)
      if (grid.valid(c, r)) sum += grid.z(c, r), ++n;
    return n > 0 ? sum / n : std::numeric_limits<double>::quiet_NaN();
  };
  pole_north_ = pole_value(0, 90.0);
  pole_south_ = pole_value(grid.height - 1, -90.0);
}

double GeoField::at(double lon, double lat) const {
  if (period_ > 0) lon = one_meridian(lon);
  if (lat > g_.north && pole_north_ == pole_north_) return toward_pole(on_row(lon, 0), 0, pole_north_, lat);
  if (lat < g_.lat(g_.height - 1) && pole_south_ == pole_south_)
    return toward_pole(on_row(lon, g_.height - 1), g_.height - 1, pole_south_, lat);
  const double col = (lon - g_.west) / g_.dlon, row = (g_.north - lat) / g_.dlat;
  const double lo = -kPad, chi = g_.width - 1 + kPad, rhi = g_.height - 1 + kPad;
  if (!(row >= lo && row <= rhi) || (period_ == 0 && !(col >= lo && col <= chi))) return background_;
  const int c =
      period_ > 0 ? int(std::floor(col)) : std::clamp(int(std::floor(col)), -kPad, g_.width - 2 + kPad);
  const int r = std::clamp(int(std::floor(row)), -kPad, g_.height - 2 + kPad);
  const double fx = col - c, fy = row - r;
  const double top = value(c, r) + fx * (value(c + 1, r) - value(c, r));
  const double bottom = value(c, r + 1) + fx * (value(c + 1, r + 1) - value(c, r + 1));
  return top + fy * (bottom - top);
}

bool GeoField::at_terrain_edge(double lon, double lat) const {
  if (period_ > 0) lon = one_meridian(lon);
  const double col = (lon - g_.west) / g_.dlon, row = (g_.north - lat) / g_.dlat;
  if (row < 0.0 && pole_north_ == pole_north_) return false;  // toward the pole: terrain
  if (row > g_.height - 1 && pole_south_ == pole_south_) return false;
  const double lo = -kPad, chi = g_.width - 1 + kPad, rhi = g_.height - 1 + kPad;
  if (!(row >= lo && row <= rhi) || (period_ == 0 && !(col >= lo && col <= chi))) return false;
  const int c =
      period_ > 0 ? int(std::floor(col)) : std::clamp(int(std::floor(col)), -kPad, g_.width - 2 + kPad);
  const int r = std::clamp(int(std::floor(row)), -kPad, g_.height - 2 + kPad);
  if (terrain(c, r) && terrain(c + 1, r) && terrain(c, r + 1) && terrain(c + 1, r + 1)) return false;
  // Tiles span as many degrees of longitude as of latitude: at 80 degrees, where a cell is about
  // six rows wide in degrees, a vertex three rows off the terrain still joined it in slivers.
  const double wider = std::max(g_.dlon, g_.dlat);
  const int rows = int(std::ceil(2.0 * wider / g_.dlat)), cols = int(std::ceil(2.0 * wider / g_.dlon));
  for (int j = r + 1 - rows; j <= r + rows; ++j)
    for (int i = c + 1 - cols; i <= c + cols; ++i)
      if (terrain(i, j)) return true;
  return false;
}

double GeoField::on_row(double lon, int r) const {
  if (period_ > 0) lon = one_meridian(lon);
  const double col = (lon - g_.west) / g_.dlon;
  if (period_ == 0 && !(col >= -kPad && col <= g_.width - 1 + kPad)) return background_;
  const int c =
      period_ > 0 ? int(std::floor(col)) : std::clamp(int(std::floor(col)), -kPad, g_.width - 2 + kPad);
  const double fx = col - c;
  return value(c, r) + fx * (value(c + 1, r) - value(c, r));
}

double GeoField::on_col(int c, double lat) const {
  if (lat > g_.north && pole_north_ == pole_north_) return toward_pole(value(c, 0), 0, pole_north_, lat);
  if (lat < g_.lat(g_.height - 1) && pole_south_ == pole_south_)
    return toward_pole(value(c, g_.height - 1), g_.height - 1, pole_south_, lat);
  const double row = (g_.north - lat) / g_.dlat;
  if (!(row >= -kPad && row <= g_.height - 1 + kPad)) return background_;
  const int r = std::clamp(int(std::floor(row)), -kPad, g_.height - 2 + kPad);
  const double fy = row - r;
  return value(c, r) + fy * (value(c, r + 1) - value(c, r));
}

TileMesh mesh_tile(const GeoField& field, const GeoRect& rect, const TileMeshOptions& options) {
  return TileGreedy(field, rect, options).run();
}

double tile_error(const GeoField& field, const GeoRect& rect, const std::vector<std::array<int, 2>>& uv,
                  const std::vector<double>& decoded,
                  const std::vector<std::array<std::uint32_t, 3>>& triangles, bool samples_only) {
  const GeoGrid& g = field.grid();
  const TileFrame fr(g, rect);
  const BackgroundPoints background = samples_only ? BackgroundPoints() : BackgroundPoints(g, fr);
  double worst = 0;
  for (const auto& tri : triangles) {
    UV p[3];
    double h[3];
    for (int k = 0; k < 3; ++k) {
      p[k] = {double(uv[tri[std::size_t(k)]][0]), double(uv[tri[std::size_t(k)]][1])};
      h[k] = decoded[tri[std::size_t(k)]];
    }
    const Plane plane(p, h);
    scan_lattice(fr, g.width, g.height, p, [&](int c, int r, double u, double v) {
      if (u < 0 || u > kQ || v < 0 || v > kQ) return;
      const bool sample = c >= 0 && r >= 0 && c < g.width && r < g.height;
      if (samples_only && !sample) return;
      const double value = field.lattice(c, r);
      if (value == value) worst = std::max(worst, std::abs(plane(u, v) - value));
    });
    scan_row_points(field, fr, p, [&](int c, int r, double u, double v, double z) {
      if (u < 0 || u > kQ || v < 0 || v > kQ) return;
      const bool samples = c >= 0 && r >= 0 && c + 1 < g.width && r < g.height;
      if (!samples_only || samples) worst = std::max(worst, std::abs(plane(u, v) - z));
    });
    background.for_each(std::min({p[0].u, p[1].u, p[2].u}), std::max({p[0].u, p[1].u, p[2].u}),
                        std::min({p[0].v, p[1].v, p[2].v}), std::max({p[0].v, p[1].v, p[2].v}),
                        [&](const UV& b) {
                          if (in_closed_triangle(p, b.u, b.v))
                            worst = std::max(worst, std::abs(plane(b.u, b.v) - field.background()));
                        });
  }
  return worst;
}

}  // namespace terralod::blocks::detail
