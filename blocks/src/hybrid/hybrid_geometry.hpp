// Private exact-geometry helpers of the hybrid grid + TIN model: lattice points, orientation,
// segment tests and ear clipping of small polygons (used for splitting TIN triangles at
// intersection vertices and for T-junction removal).
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace terralod::blocks::hybrid::detail {

/// Lattice resolution: 1/65536 of a sample (coordinates below 2^32 for DEMs up to 65535 samples
/// a side); orientation products are evaluated in 128 bits.
constexpr std::int64_t kScale = 65536;

struct LPoint {
  std::int64_t x = 0, y = 0;
  bool operator==(const LPoint&) const = default;
};

inline std::int64_t orient(const LPoint& a, const LPoint& b, const LPoint& c) {
  const __int128 v = __int128(b.x - a.x) * (c.y - a.y) - __int128(b.y - a.y) * (c.x - a.x);
  return v > 0 ? 1 : (v < 0 ? -1 : 0);
}

/// Twice the signed area of a polygon (exact), as a double.
inline double area2(const std::vector<LPoint>& poly) {
  __int128 s = 0;
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const LPoint& a = poly[i];
    const LPoint& b = poly[(i + 1) % poly.size()];
    s += __int128(a.x) * b.y - __int128(b.x) * a.y;
  }
  return double(s);
}

/// True when p lies on the closed segment ab.
inline bool on_segment(const LPoint& a, const LPoint& b, const LPoint& p) {
  if (orient(a, b, p) != 0) return false;
  return std::min(a.x, b.x) <= p.x && p.x <= std::max(a.x, b.x) && std::min(a.y, b.y) <= p.y &&
         p.y <= std::max(a.y, b.y);
}

/// True when closed segments ab and cd share a point.
inline bool segments_meet(const LPoint& a, const LPoint& b, const LPoint& c, const LPoint& d) {
  const auto o1 = orient(a, b, c), o2 = orient(a, b, d), o3 = orient(c, d, a), o4 = orient(c, d, b);
  if (o1 != o2 && o3 != o4 && o1 * o2 <= 0 && o3 * o4 <= 0) return true;
  return on_segment(a, b, c) || on_segment(a, b, d) || on_segment(c, d, a) || on_segment(c, d, b);
}

/// Triangulates a simple CCW polygon (indices into pts) by ear clipping; ears must be strictly
/// convex and contain no other polygon vertex (closed test). Returns false if it gets stuck.
inline bool ear_clip(const std::vector<LPoint>& pts, std::vector<std::uint32_t> poly,
                     std::vector<std::array<std::uint32_t, 3>>& out) {
  while (poly.size() > 3) {
    bool clipped = false;
    const std::size_t n = poly.size();
    for (std::size_t i = 0; i < n && !clipped; ++i) {
      const std::uint32_t a = poly[(i + n - 1) % n], b = poly[i], c = poly[(i + 1) % n];
      if (orient(pts[a], pts[b], pts[c]) <= 0) continue;
      bool empty = true;
      for (std::uint32_t v : poly) {
        if (v == a || v == b || v == c) continue;
        const LPoint& p = pts[v];
        if (p == pts[a] || p == pts[b] || p == pts[c]) continue;
        if (orient(pts[a], pts[b], p) >= 0 && orient(pts[b], pts[c], p) >= 0 &&
            orient(pts[c], pts[a], p) >= 0) {
          empty = false;
          break;
        }
      }
      if (!empty) continue;
      out.push_back({a, b, c});
      poly.erase(poly.begin() + std::ptrdiff_t(i));
      clipped = true;
    }
    if (!clipped) return false;
  }
  if (poly.size() == 3) {
    if (orient(pts[poly[0]], pts[poly[1]], pts[poly[2]]) <= 0) return false;
    out.push_back({poly[0], poly[1], poly[2]});
  }
  return true;
}

}  // namespace terralod::blocks::hybrid::detail
