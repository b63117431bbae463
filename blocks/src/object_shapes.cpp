// Extruded shapes (object_shapes.hpp): footprints planned once by ear clipping with hole
// bridging (D. Eberly, "Triangulation by Ear Clipping", sections 2-5) on exactly snapped
// integer coordinates, then per frame a closed solid from the lowest to the highest drawn
// ground under the footprint's box (the drawn triangles there clipped to the box) plus the
// height. Memory: see the header; extrude() reuses its caller's mesh and one index buffer.
#include "terralod/blocks/object_shapes.hpp"

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>

#include "terralod/blocks/object_rules.hpp"

namespace terralod::blocks {

namespace {

using i128 = __int128;

// A vertex snapped to the footprint's integer grid: |x|, |y| <= 2^30 + 1 for every vertex
// inside the exterior ring's box, so differences fit 32 bits and products of two fit 64.
struct IPoint {
  std::int64_t x = 0, y = 0;
  bool operator==(const IPoint&) const = default;
};

// Twice the signed area of (a, b, c), exact: > 0 when c is left of a -> b.
i128 orient(IPoint a, IPoint b, IPoint c) {
  return i128(b.x - a.x) * i128(c.y - a.y) - i128(b.y - a.y) * i128(c.x - a.x);
}
int sign(i128 v) { return (v > 0) - (v < 0); }

// q in the closed triangle (a, b, c), counter-clockwise.
bool in_triangle(IPoint a, IPoint b, IPoint c, IPoint q) {
  return orient(a, b, q) >= 0 && orient(b, c, q) >= 0 && orient(c, a, q) >= 0;
}

// q strictly inside the open segment (a, b).
bool on_open_segment(IPoint a, IPoint b, IPoint q) {
  if (orient(a, b, q) != 0) return false;
  const i128 t = i128(q.x - a.x) * (b.x - a.x) + i128(q.y - a.y) * (b.y - a.y);
  const i128 len2 = i128(b.x - a.x) * (b.x - a.x) + i128(b.y - a.y) * (b.y - a.y);
  return t > 0 && t < len2;
}

// The open segments (a, b) and (c, d) cross at one point interior to both.
bool cross_properly(IPoint a, IPoint b, IPoint c, IPoint d) {
  return sign(orient(a, b, c)) * sign(orient(a, b, d)) < 0 &&
         sign(orient(c, d, a)) * sign(orient(c, d, b)) < 0;
}

// Direction v -> q leaves v into the open interior wedge of a -> v -> b (interior on the left).
bool in_wedge(IPoint a, IPoint v, IPoint b, IPoint q) {
  const bool left_in = orient(a, v, q) > 0, left_out = orient(v, b, q) > 0;
  return orient(a, v, b) > 0 ? (left_in && left_out) : (left_in || left_out);
}

i128 ring_area2(const std::vector<IPoint>& p, std::size_t begin, std::size_t end) {
  i128 a = 0;
  for (std::size_t k = begin; k < end; ++k) {
    const IPoint& u = p[k];
    const IPoint& w = p[k + 1 == end ? begin : k + 1];
    a += i128(u.x) * w.y - i128(w.x) * u.y;
  }
  return a;
}

// Bridges hole `h` (ring h of f, its snapped points in `ip`) into the merged polygon `poly`
// (indices into f.points): from the hole's vertex of largest x to the nearest boundary vertex
// that sees it (exact tests against every edge of the polygon and of the holes not yet merged).
bool bridge_hole(const ShapeFootprint& f, const std::vector<IPoint>& ip, std::size_t h,
                 const std::vector<bool>& merged, std::vector<std::uint32_t>& poly) {
  const std::uint32_t h0 = f.ring_start[h], h1 = f.ring_start[h + 1], hn = h1 - h0;
  std::uint32_t mi = h0;
  for (std::uint32_t k = h0; k < h1; ++k)
    if (ip[k].x > ip[mi].x || (ip[k].x == ip[mi].x && ip[k].y > ip[mi].y)) mi = k;
  const IPoint m = ip[mi];
  const IPoint mprev = ip[mi == h0 ? h1 - 1 : mi - 1], mnext = ip[mi + 1 == h1 ? h0 : mi + 1];
  std::vector<std::size_t> order(poly.size());
  std::iota(order.begin(), order.end(), std::size_t(0));
  const auto dist2 = [&](std::size_t k) {
    const IPoint& p = ip[poly[k]];
    return i128(p.x - m.x) * (p.x - m.x) + i128(p.y - m.y) * (p.y - m.y);
  };
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return dist2(a) < dist2(b); });
  // Every edge that a bridge must not cross: the merged polygon's and the unmerged holes'.
  const auto blocked = [&](IPoint v) {
    const std::size_t n = poly.size();
    for (std::size_t k = 0; k < n; ++k) {
      const IPoint a = ip[poly[k]], b = ip[poly[(k + 1) % n]];
      if (on_open_segment(v, m, a) || cross_properly(v, m, a, b)) return true;
    }
    for (std::size_t r = 1; r + 1 < f.ring_start.size(); ++r) {
      if (merged[r]) continue;
      for (std::uint32_t k = f.ring_start[r]; k < f.ring_start[r + 1]; ++k) {
        const IPoint a = ip[k], b = ip[k + 1 == f.ring_start[r + 1] ? f.ring_start[r] : k + 1];
        if (on_open_segment(v, m, a) || cross_properly(v, m, a, b)) return true;
      }
    }
    return false;
  };
  for (const std::size_t k : order) {
    const std::size_t n = poly.size();
    const IPoint v = ip[poly[k]];
    if (v == m) continue;
    if (!in_wedge(ip[poly[(k + n - 1) % n]], v, ip[poly[(k + 1) % n]], m)) continue;
    if (!in_wedge(mprev, m, mnext, v)) continue;
    if (blocked(v)) continue;
    // poly[..k], the hole from m around back to m, poly[k] again, poly[k+1..].
    std::vector<std::uint32_t> out;
    out.reserve(n + hn + 2);
    out.insert(out.end(), poly.begin(), poly.begin() + std::ptrdiff_t(k) + 1);
    for (std::uint32_t j = 0; j <= hn; ++j) out.push_back(h0 + (mi - h0 + j) % hn);
    out.push_back(poly[k]);
    out.insert(out.end(), poly.begin() + std::ptrdiff_t(k) + 1, poly.end());
    poly.swap(out);
    return true;
  }
  return false;
}

// Ear clipping of the weakly simple polygon `poly` (counter-clockwise). A vertex at the same
// position as a corner of the candidate ear (a bridge's twin) does not block it: its edges lie
// outside the corner's interior wedge. False when no ear is left but area is.
bool clip_ears(const std::vector<IPoint>& ip, const std::vector<std::uint32_t>& poly,
               std::vector<std::array<std::uint32_t, 3>>& out) {
  const std::size_t n = poly.size();
  std::vector<std::size_t> prev(n), next(n);
  for (std::size_t k = 0; k < n; ++k) prev[k] = (k + n - 1) % n, next[k] = (k + 1) % n;
  const auto at = [&](std::size_t k) { return ip[poly[k]]; };
  const auto is_ear = [&](std::size_t i) {
    const IPoint a = at(prev[i]), b = at(i), c = at(next[i]);
    if (orient(a, b, c) <= 0) return false;
    for (std::size_t j = next[next[i]]; j != prev[i]; j = next[j]) {
      const IPoint q = at(j);
      if (q == a || q == b || q == c) continue;
      if (in_triangle(a, b, c, q)) return false;
    }
    return true;
  };
  std::size_t remaining = n, i = 0, stall = 0;
  while (remaining >= 3 && stall < remaining) {
    if (is_ear(i)) {
      out.push_back({poly[prev[i]], poly[i], poly[next[i]]});
      next[prev[i]] = next[i], prev[next[i]] = prev[i];
      i = prev[i], --remaining, stall = 0;
    } else {
      i = next[i], ++stall;
    }
  }
  if (remaining < 3) return true;
  i128 left = 0;  // what no ear could take must have no area (a bridge and its twin)
  std::size_t k = i;
  do {
    const IPoint u = at(k), w = at(next[k]);
    left += i128(u.x) * w.y - i128(w.x) * u.y;
    k = next[k];
  } while (k != i);
  return left == 0;
}

}  // namespace

ShapeFootprint plan_footprint(const std::vector<std::vector<WorldPoint>>& rings) {
  ShapeFootprint f;
  if (rings.empty() || rings[0].empty()) return f;
  f.min = f.max = rings[0][0];
  for (const std::vector<WorldPoint>& r : rings)
    for (const WorldPoint& p : r)
      if (!std::isfinite(p.x) || !std::isfinite(p.y)) return f;
  for (const WorldPoint& p : rings[0]) {
    f.min.x = std::min(f.min.x, p.x), f.min.y = std::min(f.min.y, p.y);
    f.max.x = std::max(f.max.x, p.x), f.max.y = std::max(f.max.y, p.y);
  }
  const double side = std::max(f.max.x - f.min.x, f.max.y - f.min.y);
  if (!(side > 0)) return f;
  constexpr double kGrid = 1073741824.0;  // 2^30 steps across the larger side of the box
  const double scale = kGrid / side;
  const auto snap = [&](const WorldPoint& p) {
    return IPoint{std::llround((p.x - f.min.x) * scale), std::llround((p.y - f.min.y) * scale)};
  };
  // Normalised rings: no repeated or closing vertex, exterior CCW, holes CW.
  std::vector<IPoint> ip;
  std::vector<std::uint32_t> keep;
  f.ring_start.push_back(0);
  for (std::size_t r = 0; r < rings.size(); ++r) {
    keep.clear();
    for (std::uint32_t k = 0; k < rings[r].size(); ++k) {
      const IPoint q = snap(rings[r][k]);
      if (q.x < 0 || q.y < 0 || q.x > std::int64_t(kGrid) || q.y > std::int64_t(kGrid)) {  // hole outside
        f.points.clear(), f.ring_start.clear();
        f.status = ShapeFootprint::Status::NotSimple;
        return f;
      }
      if (keep.empty() || !(snap(rings[r][keep.back()]) == q)) keep.push_back(k);
    }
    while (keep.size() > 1 && snap(rings[r][keep.back()]) == snap(rings[r][keep.front()])) keep.pop_back();
    std::vector<IPoint> q(keep.size());
    for (std::size_t k = 0; k < keep.size(); ++k) q[k] = snap(rings[r][keep[k]]);
    const i128 a2 = keep.size() >= 3 ? ring_area2(q, 0, q.size()) : 0;
    if (a2 == 0) {
      if (r == 0) return f;  // Degenerate: no roof
      continue;              // a hole without area is no hole
    }
    if ((a2 > 0) != (r == 0)) std::reverse(keep.begin(), keep.end());
    for (const std::uint32_t k : keep) f.points.push_back(rings[r][k]), ip.push_back(snap(rings[r][k]));
    f.ring_start.push_back(std::uint32_t(f.points.size()));
  }
  // Area in doubles, relative to the box corner (exact enough for world coordinates of any size).
  for (std::size_t r = 0; r + 1 < f.ring_start.size(); ++r)
    for (std::uint32_t k = f.ring_start[r]; k < f.ring_start[r + 1]; ++k) {
      const WorldPoint& u = f.points[k];
      const WorldPoint& w = f.points[k + 1 == f.ring_start[r + 1] ? f.ring_start[r] : k + 1];
      f.area += 0.5 * ((u.x - f.min.x) * (w.y - f.min.y) - (w.x - f.min.x) * (u.y - f.min.y));
    }
  // Holes bridged in decreasing order of their largest x (Eberly, section 5), then ears.
  const std::size_t ring_count = f.ring_start.size() - 1;
  std::vector<std::uint32_t> poly(f.ring_start[1]);
  std::iota(poly.begin(), poly.end(), std::uint32_t(0));
  std::vector<std::size_t> holes;
  std::vector<std::int64_t> max_x(ring_count, std::numeric_limits<std::int64_t>::min());
  for (std::size_t r = 1; r < ring_count; ++r) {
    holes.push_back(r);
    for (std::uint32_t k = f.ring_start[r]; k < f.ring_start[r + 1]; ++k)
      max_x[r] = std::max(max_x[r], ip[k].x);
  }
  std::stable_sort(holes.begin(), holes.end(),
                   [&](std::size_t a, std::size_t b) { return max_x[a] > max_x[b]; });
  std::vector<bool> merged(ring_count, false);
  merged[0] = true;
  bool ok = true;
  for (const std::size_t h : holes) {
    if (!(ok = bridge_hole(f, ip, h, merged, poly))) break;
    merged[h] = true;
  }
  if (ok) ok = clip_ears(ip, poly, f.roof);
  if (ok) {  // exact check: the ears cover exactly the polygon's area, with every vertex
    i128 polygon = 0, ears = 0;
    for (std::size_t r = 0; r < ring_count; ++r)
      polygon += ring_area2(ip, f.ring_start[r], f.ring_start[r + 1]);
    for (const auto& t : f.roof) ears += orient(ip[t[0]], ip[t[1]], ip[t[2]]);
    ok = polygon == ears && f.roof.size() == f.points.size() + 2 * (ring_count - 1) - 2;
  }
  if (!ok) {
    f.roof.clear();
    f.status = ShapeFootprint::Status::NotSimple;
    return f;
  }
  f.status = ShapeFootprint::Status::Ok;
  return f;
}

namespace {

// Lowest and highest z of triangle (a, b, c) clipped in plan to the box [x0, x1] x [y0, y1]
// (Sutherland-Hodgman, z interpolated along the edges: the triangle's plane); lo, hi unchanged
// when they do not meet.
void clipped_range(const pm::Vec3& a, const pm::Vec3& b, const pm::Vec3& c, double x0, double y0, double x1,
                   double y1, double& lo, double& hi) {
  std::array<pm::Vec3, 16> buf[2];
  std::size_t n = 3;
  buf[0][0] = a, buf[0][1] = b, buf[0][2] = c;
  int cur = 0;
  for (int side = 0; side < 4 && n > 0; ++side) {
    const auto inside = [&](const pm::Vec3& p) {
      return side == 0 ? p.x >= x0 : side == 1 ? p.x <= x1 : side == 2 ? p.y >= y0 : p.y <= y1;
    };
    const auto cut = [&](const pm::Vec3& p, const pm::Vec3& q) {
      const double s = side < 2 ? ((side == 0 ? x0 : x1) - p.x) / (q.x - p.x)
                                : ((side == 2 ? y0 : y1) - p.y) / (q.y - p.y);
      pm::Vec3 r{p.x + s * (q.x - p.x), p.y + s * (q.y - p.y), p.z + s * (q.z - p.z)};
      if (side < 2)
        r.x = side == 0 ? x0 : x1;  // exactly on the box
      else
        r.y = side == 2 ? y0 : y1;
      return r;
    };
    const std::array<pm::Vec3, 16>& in = buf[cur];
    std::array<pm::Vec3, 16>& out = buf[1 - cur];
    std::size_t m = 0;
    for (std::size_t k = 0; k < n; ++k) {
      const pm::Vec3& p = in[k];
      const pm::Vec3& q = in[(k + 1) % n];
      const bool pin = inside(p), qin = inside(q);
      if (pin) out[m++] = p;
      if (pin != qin) out[m++] = cut(p, q);
    }
    n = m, cur = 1 - cur;
  }
  for (std::size_t k = 0; k < n; ++k) lo = std::min(lo, buf[cur][k].z), hi = std::max(hi, buf[cur][k].z);
}

}  // namespace

ShapeExtruder::ShapeExtruder(const ObjectPlacer& placer, const ObjectShapeOptions& options)
    : placer_(placer) {
  if (!(std::isfinite(options.default_height_m) && options.default_height_m > 0))
    throw std::invalid_argument("ObjectShapeOptions::default_height_m must be finite and > 0");
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<MapObject>& objects = placer.objects();
  plans_.resize(objects.size());
  heights_.assign(objects.size(), 0.0);
  for (std::size_t i = 0; i < objects.size(); ++i) {
    const MapObject& m = objects[i];
    if (m.feature.geometry != GeometryType::Polygon) continue;
    ++plan_stats_.polygons;
    plans_[i] = plan_footprint(m.feature.rings);
    plan_stats_.degenerate += plans_[i].status == ShapeFootprint::Status::Degenerate;
    plan_stats_.not_simple += plans_[i].status == ShapeFootprint::Status::NotSimple;
    const std::string& field = placer.layers().at(m.layer).height_field;
    const ObjectAttribute* a = field.empty() ? nullptr : m.feature.attribute(field);
    const double h = a ? priority_value(a->value) : 0.0;  // finite, else 0
    heights_[i] = h > 0 ? h : options.default_height_m;
    plan_stats_.default_heights += !(h > 0);
  }
  plan_stats_.plan_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

void ShapeExtruder::extrude(const TerrainRuntime& rt, std::span<const PlacedObject> placed, ObjectMesh& out) {
  const auto t0 = std::chrono::steady_clock::now();
  out.clear();
  stats_ = {};
  const std::vector<MapObject>& objects = placer_.objects();
  const DrawnMesh& drawn = rt.drawn_mesh();
  for (const PlacedObject& p : placed) {
    assert(p.object >= objects.data() && p.object < objects.data() + objects.size());
    const auto index = std::size_t(p.object - objects.data());
    if (p.object->feature.geometry != GeometryType::Polygon) {
      ++stats_.not_polygons;
      continue;
    }
    const ShapeFootprint& f = plans_[index];
    if (f.empty()) {
      ++stats_.empty_plans;
      continue;
    }
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    bool drawn_under = true;
    for (const WorldPoint& q : f.points) {
      const double z = rt.drawn_height(q.x, q.y);
      if (std::isnan(z)) {
        drawn_under = false;
        break;
      }
      lo = std::min(lo, z), hi = std::max(hi, z);
    }
    if (!drawn_under) {
      ++stats_.skipped_undrawn;
      continue;
    }
    rt.drawn_triangles_in(f.min.x, f.min.y, f.max.x, f.max.y, tris_);
    stats_.drawn_triangles += tris_.size();
    for (const std::uint32_t t : tris_) {
      const auto& tri = drawn.triangles[t];
      const pm::Vec3 &a = drawn.positions[tri[0]], &b = drawn.positions[tri[1]], &c = drawn.positions[tri[2]];
      if (std::max({a.x, b.x, c.x}) < f.min.x || std::min({a.x, b.x, c.x}) > f.max.x ||
          std::max({a.y, b.y, c.y}) < f.min.y || std::min({a.y, b.y, c.y}) > f.max.y)
        continue;
      if (std::min({a.z, b.z, c.z}) >= lo && std::max({a.z, b.z, c.z}) <= hi) continue;  // changes nothing
      clipped_range(a, b, c, f.min.x, f.min.y, f.max.x, f.max.y, lo, hi);
    }
    const double base = lo, roof = hi + heights_[index];
    const auto object = std::uint32_t(index);
    // Walls: one quad per ring edge; the solid is left of the edge, so outward is its right.
    for (std::size_t r = 0; r + 1 < f.ring_start.size(); ++r)
      for (std::uint32_t k = f.ring_start[r]; k < f.ring_start[r + 1]; ++k) {
        const WorldPoint& u = f.points[k];
        const WorldPoint& w = f.points[k + 1 == f.ring_start[r + 1] ? f.ring_start[r] : k + 1];
        const double len = std::hypot(w.x - u.x, w.y - u.y);
        const pm::Vec3 normal{(w.y - u.y) / len, -(w.x - u.x) / len, 0.0};
        const auto v = std::uint32_t(out.positions.size());
        out.positions.insert(out.positions.end(),
                             {{u.x, u.y, base}, {w.x, w.y, base}, {w.x, w.y, roof}, {u.x, u.y, roof}});
        out.normals.insert(out.normals.end(), 4, normal);
        out.triangles.push_back({v, v + 1, v + 2});
        out.triangles.push_back({v, v + 2, v + 3});
        out.triangle_object.insert(out.triangle_object.end(), 2, object);
      }
    // Roof (up) and floor (down, the roof's triangles reversed).
    const auto top = std::uint32_t(out.positions.size());
    for (const WorldPoint& q : f.points) out.positions.push_back({q.x, q.y, roof});
    out.normals.insert(out.normals.end(), f.points.size(), pm::Vec3{0.0, 0.0, 1.0});
    const auto bottom = std::uint32_t(out.positions.size());
    for (const WorldPoint& q : f.points) out.positions.push_back({q.x, q.y, base});
    out.normals.insert(out.normals.end(), f.points.size(), pm::Vec3{0.0, 0.0, -1.0});
    for (const auto& t : f.roof) {
      out.triangles.push_back({top + t[0], top + t[1], top + t[2]});
      out.triangles.push_back({bottom + t[0], bottom + t[2], bottom + t[1]});
    }
    out.triangle_object.insert(out.triangle_object.end(), 2 * f.roof.size(), object);
    ++stats_.shapes;
  }
  stats_.extrude_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace terralod::blocks
