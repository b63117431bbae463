// Exact per-triangle error with its location, for the greedy TIN and the non-regular grid.
#include "tin_error.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdlib>
#include <utility>

namespace terralod::blocks::detail {
namespace {

inline std::int64_t floor_div(std::int64_t a, std::int64_t b) {
  assert(b > 0);
  std::int64_t q = a / b;
  return (a % b != 0 && a < 0) ? q - 1 : q;
}

/// Exact span [xl, xr] of the closed triangle with edge functions A x + B y + C >= 0 on row y
/// (empty when xl > xr). The bound -Cy/A is a quotient of integers below 2^31, so its double is
/// correctly rounded and floor/ceil of the double equal floor/ceil of the exact quotient.
inline void row_span(const std::int64_t A[3], const std::int64_t B[3], const std::int64_t C[3], int y,
                     std::int64_t& xl, std::int64_t& xr) {
  for (int k = 0; k < 3; ++k) {
    const std::int64_t Cy = B[k] * y + C[k];  // A x + Cy >= 0 inside
    if (A[k] > 0)
      xl = std::max(xl, std::int64_t(std::ceil(double(-Cy) / double(A[k]))));
    else if (A[k] < 0)
      xr = std::min(xr, std::int64_t(std::floor(double(Cy) / double(-A[k]))));
    else if (Cy < 0)
      xr = xl - 1;
  }
}

/// Edge functions of the CCW-ordered triangle (a,b,c) (b and c swapped when clockwise); returns
/// twice its area.
inline std::int64_t edge_functions(pm::GridPoint& a, pm::GridPoint& b, pm::GridPoint& c, std::int64_t A[3],
                                   std::int64_t B[3], std::int64_t C[3]) {
  std::int64_t area2 = pm::orient2d(a, b, c);
  assert(area2 != 0);
  if (area2 < 0) std::swap(b, c), area2 = -area2;
  const pm::GridPoint P[3] = {a, b, c};
  for (int k = 0; k < 3; ++k) {
    const pm::GridPoint s = P[(k + 1) % 3], e = P[(k + 2) % 3];
    A[k] = -(std::int64_t(e.y) - s.y);
    B[k] = std::int64_t(e.x) - s.x;
    C[k] = -(A[k] * s.x + B[k] * s.y);
  }
  return area2;
}

}  // namespace

void mark_triangle(pm::GridPoint a, pm::GridPoint b, pm::GridPoint c, int x0, int y0, int width,
                   std::vector<std::uint8_t>& mask) {
  std::int64_t A[3], B[3], C[3];
  edge_functions(a, b, c, A, B, C);
  const int xmin = std::min({a.x, b.x, c.x}), xmax = std::max({a.x, b.x, c.x});
  for (int y = std::min({a.y, b.y, c.y}); y <= std::max({a.y, b.y, c.y}); ++y) {
    std::int64_t xl = xmin, xr = xmax;
    row_span(A, B, C, y, xl, xr);
    for (std::int64_t x = xl; x <= xr; ++x) mask[std::size_t(y - y0) * width + std::size_t(x - x0)] = 1;
  }
}

SampleScan scan_triangle(const pm::Heightfield& hf, pm::GridPoint a, pm::GridPoint b, pm::GridPoint c) {
  // Same edge functions and evaluation order as LInfError::samples_in_triangle, so that the
  // values are bit-identical.
  std::int64_t A[3], B[3], C[3];
  const std::int64_t area2 = edge_functions(a, b, c, A, B, C);
  const double Z[3] = {hf.at(a.x, a.y), hf.at(b.x, b.y), hf.at(c.x, c.y)};
  const double sx = double(A[0]) * Z[0] + double(A[1]) * Z[1] + double(A[2]) * Z[2];
  const double W = double(area2);
  const int y0 = std::min({a.y, b.y, c.y}), y1 = std::max({a.y, b.y, c.y});
  const int xmin = std::min({a.x, b.x, c.x}), xmax = std::max({a.x, b.x, c.x});
  const int width = hf.width();
  const double* z0 = hf.samples().data();
  const std::uint8_t* m0 = hf.has_holes() ? hf.mask().data() : nullptr;
  double best = 0.0;      // largest |numerator| of a candidate sample
  double best_any = 0.0;  // largest |numerator| of any valid sample (corners included)
  int bx = -1, by = -1;
  for (int y = y0; y <= y1; ++y) {
    std::int64_t xl = xmin, xr = xmax;
    row_span(A, B, C, y, xl, xr);
    if (xl > xr) continue;
    const double sy =
        double(B[0] * y + C[0]) * Z[0] + double(B[1] * y + C[1]) * Z[1] + double(B[2] * y + C[2]) * Z[2];
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
    if (rmax <= best) continue;
    const pm::GridPoint p{int(rx), y};
    if (!(p == a || p == b || p == c)) {
      best = rmax, bx = int(rx), by = y;
      continue;
    }
    // The row's maximum is a corner (rounding noise only): find the best non-corner sample.
    for (std::int64_t x = xl; x <= xr; ++x) {
      const pm::GridPoint q{int(x), y};
      if ((m0 && !m0[row + x]) || q == a || q == b || q == c) continue;
      const double d = std::abs((sx * double(x) + sy) - W * zr[x]);
      if (d > best) best = d, bx = int(x), by = y;
    }
  }
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
    const std::int64_t N = std::int64_t(a.y) * D + t * (std::int64_t(b.y) - a.y), j = floor_div(N, D);
    r = N - j * D;
    s0 = {int(a.x + t), int(j)}, s1 = {int(a.x + t), int(j) + 1};
  };
  auto horizontal = [](pm::GridPoint a, pm::GridPoint b, std::int64_t D, std::int64_t t, pm::GridPoint& s0,
                       pm::GridPoint& s1, std::int64_t& r) {
    const std::int64_t N = std::int64_t(a.x) * D + t * (std::int64_t(b.x) - a.x), i = floor_div(N, D);
    r = N - i * D;
    s0 = {int(i), int(a.y + t)}, s1 = {int(i) + 1, int(a.y + t)};
  };
  auto diagonal = [](pm::GridPoint a, pm::GridPoint b, std::int64_t D, std::int64_t t, pm::GridPoint& s0,
                     pm::GridPoint& s1, std::int64_t& r) {
    const std::int64_t k = std::int64_t(a.x - a.y) + t;
    const std::int64_t N = std::int64_t(a.x) * D + t * (std::int64_t(b.x) - a.x), i = floor_div(N, D);
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

}  // namespace terralod::blocks::detail
