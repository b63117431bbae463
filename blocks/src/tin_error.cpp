// Exact per-triangle error with its location, for the greedy TIN and the non-regular grid.
#include "tin_error.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdlib>
#include <utility>

#include "terralod/pm/grid_triangle.hpp"

namespace terralod::blocks::detail {
namespace {

/// The non-degenerate triangle (a,b,c), made counter-clockwise (b and c swapped when clockwise).
inline pm::GridTriangle ccw_triangle(pm::GridPoint& a, pm::GridPoint& b, pm::GridPoint& c) {
  const pm::GridTriangle t = pm::GridTriangle::ccw(a, b, c);
  assert(t.area2 != 0);
  return t;
}

}  // namespace

void mark_triangle(pm::GridPoint a, pm::GridPoint b, pm::GridPoint c, int x0, int y0, int width,
                   std::vector<std::uint8_t>& mask) {
  ccw_triangle(a, b, c).for_each_span([&](int y, std::int64_t xl, std::int64_t xr) {
    for (std::int64_t x = xl; x <= xr; ++x) mask[std::size_t(y - y0) * width + std::size_t(x - x0)] = 1;
  });
}

SampleScan scan_triangle(const pm::Heightfield& hf, pm::GridPoint a, pm::GridPoint b, pm::GridPoint c) {
  // The rasterisation and plane of LInfError::samples_in_triangle (grid_triangle.hpp), so that
  // the values are bit-identical.
  const pm::GridTriangle t = ccw_triangle(a, b, c);
  const double Z[3] = {hf.at(a.x, a.y), hf.at(b.x, b.y), hf.at(c.x, c.y)};
  const double sx = t.plane_x(Z);
  const double W = double(t.area2);
  const int width = hf.width();
  const double* z0 = hf.samples().data();
  const std::uint8_t* m0 = hf.has_holes() ? hf.mask().data() : nullptr;
  double best = 0.0;      // largest |numerator| of a candidate sample
  double best_any = 0.0;  // largest |numerator| of any valid sample (corners included)
  int bx = -1, by = -1;
  t.for_each_span([&](int y, std::int64_t xl, std::int64_t xr) {
    const double sy = t.plane_y(Z, y);
    const std::size_t row = std::size_t(y) * width;
    const double* zr = z0 + row;
    double rmax = -1.0;  // this row's largest |numerator| and where
    std::int64_t rx = -1;
    if (!m0) {
      for (std::int64_t x = xl; x <= xr; ++x) {
        const double d = std::abs((sx * double(x) + sy) - W * zr[x]);
        if (d > rmax) rmax = d, rx = x;
      }
    } else {
      const std::uint8_t* mr = m0 + row;
      for (std::int64_t x = xl; x <= xr; ++x) {
        if (!mr[x]) continue;
        const double d = std::abs((sx * double(x) + sy) - W * zr[x]);
        if (d > rmax) rmax = d, rx = x;
      }
    }
    best_any = std::max(best_any, rmax);
    if (rmax <= best) return;
    const pm::GridPoint p{int(rx), y};
    if (!(p == a || p == b || p == c)) {
      best = rmax, bx = int(rx), by = y;
      return;
    }
    // The row's maximum is a corner (rounding noise only): find the best non-corner sample.
    for (std::int64_t x = xl; x <= xr; ++x) {
      const pm::GridPoint q{int(x), y};
      if ((m0 && !m0[row + x]) || q == a || q == b || q == c) continue;
      const double d = std::abs((sx * double(x) + sy) - W * zr[x]);
      if (d > best) best = d, bx = int(x), by = y;
    }
  });
  return SampleScan{best_any / W, pm::GridPoint{bx, by}};
}

Crossing worst_crossing(const pm::Heightfield& hf, pm::GridPoint p, pm::GridPoint q) {
  Crossing out;
  const bool holes = hf.has_holes();
  // Walks the crossings of a-b with the lines g(x,y) = const of one family: at step t the point
  // is a + (t/D)(b - a), D = g(b) - g(a) > 0, and the crossed grid edge runs from sample s0 to
  // s1 = s0 + step, the crossing at fraction r/D from s0. The value is computed exactly as in
  // LInfError::segment (multiplied by D).
  auto family = [&](pm::GridPoint a, pm::GridPoint b, int ga, int gb, auto edge_at) {
    const std::int64_t D = std::int64_t(gb) - ga;
    if (D <= 0) return;
    const double za = hf.at(a.x, a.y), zb = hf.at(b.x, b.y);
    for (std::int64_t t = 1; t < D; ++t) {
      pm::GridPoint s0, s1;
      std::int64_t r;
      edge_at(a, b, D, t, s0, s1, r);
      if (holes && (!hf.valid(s0.x, s0.y) || (r && !hf.valid(s1.x, s1.y)))) continue;
      double orig = hf.at(s0.x, s0.y) * double(D - r);
      if (r) orig += hf.at(s1.x, s1.y) * double(r);
      const double lin = za * double(D - t) + zb * double(t);
      const double e = std::abs(lin - orig) / double(D);
      if (e > out.error || out.s0.x < 0) {
        out.error = e;
        if (!r) s1 = s0;
        if (2 * r > D) std::swap(s0, s1);
        out.s0 = s0, out.s1 = s1;
      }
    }
  };
  auto vertical = [](pm::GridPoint a, pm::GridPoint b, std::int64_t D, std::int64_t t, pm::GridPoint& s0,
                     pm::GridPoint& s1, std::int64_t& r) {
    const std::int64_t N = std::int64_t(a.y) * D + t * (std::int64_t(b.y) - a.y), j = pm::floor_div(N, D);
    r = N - j * D;
    s0 = {int(a.x + t), int(j)}, s1 = {int(a.x + t), int(j) + 1};
  };
  auto horizontal = [](pm::GridPoint a, pm::GridPoint b, std::int64_t D, std::int64_t t, pm::GridPoint& s0,
                       pm::GridPoint& s1, std::int64_t& r) {
    const std::int64_t N = std::int64_t(a.x) * D + t * (std::int64_t(b.x) - a.x), i = pm::floor_div(N, D);
    r = N - i * D;
    s0 = {int(i), int(a.y + t)}, s1 = {int(i) + 1, int(a.y + t)};
  };
  auto diagonal = [](pm::GridPoint a, pm::GridPoint b, std::int64_t D, std::int64_t t, pm::GridPoint& s0,
                     pm::GridPoint& s1, std::int64_t& r) {
    const std::int64_t k = std::int64_t(a.x - a.y) + t;
    const std::int64_t N = std::int64_t(a.x) * D + t * (std::int64_t(b.x) - a.x), i = pm::floor_div(N, D);
    r = N - i * D;
    s0 = {int(i), int(i - k)}, s1 = {int(i) + 1, int(i + 1 - k)};
  };
  if (q.x >= p.x)
    family(p, q, p.x, q.x, vertical);
  else
    family(q, p, q.x, p.x, vertical);
  if (q.y >= p.y)
    family(p, q, p.y, q.y, horizontal);
  else
    family(q, p, q.y, p.y, horizontal);
  if (q.x - q.y >= p.x - p.y)
    family(p, q, p.x - p.y, q.x - q.y, diagonal);
  else
    family(q, p, q.x - q.y, p.x - p.y, diagonal);
  return out;
}

double edge_error(const pm::LInfError& linf, const pm::Heightfield& hf, pm::GridPoint p, pm::GridPoint q) {
  return hf.has_holes() ? worst_crossing(hf, p, q).error : linf.segment(p, q);
}

double triangle_error(const pm::LInfError& linf, const pm::Heightfield& hf, pm::ErrorMetric metric,
                      pm::GridPoint a, pm::GridPoint b, pm::GridPoint c) {
  if (!hf.has_holes()) return linf.triangle(a, b, c);
  // The hole rules of scan_triangle (valid samples) and worst_crossing (grid edges between valid
  // samples), through LInfError's own code: the value it would give over the valid part.
  return pm::LInfError(hf, metric, {.skip_holes = true}).triangle(a, b, c);
}

}  // namespace terralod::blocks::detail
