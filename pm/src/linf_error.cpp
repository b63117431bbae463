// Exact L-infinity error of grid-aligned triangles: rasterised samples plus grid-edge crossings.
#include "terralod/pm/linf_error.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <utility>

#include "terralod/pm/grid_triangle.hpp"

namespace terralod::pm {

double LInfError::surface_height(double col, double row) const {
  const int W = hf_->width(), H = hf_->height();
  int i = std::clamp(int(std::floor(col)), 0, W - 2);
  int j = std::clamp(int(std::floor(row)), 0, H - 2);
  double fx = col - i, fy = row - j;
  double z00 = hf_->at(i, j), z10 = hf_->at(i + 1, j), z01 = hf_->at(i, j + 1), z11 = hf_->at(i + 1, j + 1);
  // Cell split along (i,j)-(i+1,j+1): lower-right triangle where fx >= fy.
  if (fx >= fy) return z00 + fx * (z10 - z00) + fy * (z11 - z10);
  return z00 + fy * (z01 - z00) + fx * (z11 - z01);
}

double LInfError::segment(GridPoint p, GridPoint q, double cutoff) const {
  const Heightfield& hf = *hf_;
  const double zp = hf.at(p.x, p.y), zq = hf.at(q.x, q.y);
  double worst = 0.0;
  // The crossings of a segment a -> b (heights za, zb) with one family of grid lines, D > 0
  // steps apart along it (and the samples on it): at step t = 1 .. D-1 it crosses a line
  // between the line's samples i and i + 1 (indices along the line), at i + r / D, where
  // i D + r = i0 D + t di with 0 <= r < D is tracked exactly. height(t, i, k) is the height of
  // sample i + k (k = 0, 1) of the t-th line. Heights are compared multiplied by D (exact for
  // integers). The largest difference is divided once: division by D > 0 is monotonic in
  // floating point, so max(|d|) / D is the largest of the |d| / D, bit for bit.
  auto crossings = [&](std::int64_t D, std::int64_t i0, std::int64_t di, double za, double zb,
                       auto&& height) {
    if (D <= 0) return;
    const std::int64_t qs = floor_div(di, D), rs = di - qs * D;
    std::int64_t i = i0, r = 0;
    double most = 0.0;
    for (std::int64_t t = 1; t < D; ++t) {
      i += qs, r += rs;
      if (r >= D) r -= D, ++i;
      double orig = height(t, i, 0) * double(D - r);
      if (r) orig += height(t, i, 1) * double(r);
      const double lin = za * double(D - t) + zb * double(t);
      most = std::max(most, std::abs(lin - orig));
    }
    worst = std::max(worst, most / double(D));
  };
  // Vertical lines x = a.x + t, their samples indexed by row (a.x <= b.x).
  auto vertical = [&](GridPoint a, GridPoint b, double za, double zb) {
    crossings(b.x - a.x, a.y, b.y - a.y, za, zb,
              [&](std::int64_t t, std::int64_t j, int k) { return hf.at(int(a.x + t), int(j) + k); });
  };
  // Horizontal lines y = a.y + t, their samples indexed by column (a.y <= b.y).
  auto horizontal = [&](GridPoint a, GridPoint b, double za, double zb) {
    crossings(b.y - a.y, a.x, b.x - a.x, za, zb,
              [&](std::int64_t t, std::int64_t i, int k) { return hf.at(int(i) + k, int(a.y + t)); });
  };
  // Diagonal lines x - y = a.x - a.y + t, the cells' diagonals from (i,j) to (i+1,j+1), their
  // samples indexed by column.
  auto diagonal = [&](GridPoint a, GridPoint b, double za, double zb) {
    const std::int64_t u0 = a.x - a.y;
    crossings(
        std::int64_t(b.x - b.y) - u0, a.x, b.x - a.x, za, zb,
        [&](std::int64_t t, std::int64_t i, int k) { return hf.at(int(i) + k, int(i + k - (u0 + t))); });
  };
  if (q.x >= p.x)
    vertical(p, q, zp, zq);
  else
    vertical(q, p, zq, zp);
  if (worst > cutoff) return worst;
  if (q.y >= p.y)
    horizontal(p, q, zp, zq);
  else
    horizontal(q, p, zq, zp);
  if (worst > cutoff) return worst;
  if ((q.x - q.y) >= (p.x - p.y))
    diagonal(p, q, zp, zq);
  else
    diagonal(q, p, zq, zp);
  return worst;
}

double LInfError::samples_in_triangle(GridPoint a, GridPoint b, GridPoint c, double cutoff) const {
  const Heightfield& hf = *hf_;
  // The samples inside, row by row, and the plane through the corners as numerators over
  // W = area2 (barycentric weights E_k / area2 from the edge functions; grid_triangle.hpp).
  const GridTriangle t = GridTriangle::ccw(a, b, c);
  const double Z[3] = {hf.at(a.x, a.y), hf.at(b.x, b.y), hf.at(c.x, c.y)};
  const double sx = t.plane_x(Z);
  const double W = double(t.area2);
  const int width = hf.width();
  const double* zrow0 = hf.samples().data();
  double hi = 0.0, lo = 0.0;  // max and min of numerator(x) - W z, numerator space
  t.for_each_span([&](int y, std::int64_t xl, std::int64_t xr) {
    const double sy = t.plane_y(Z, y);
    const double* zr = zrow0 + std::size_t(y) * width;
    double rhi = hi, rlo = lo;
    for (std::int64_t x = xl; x <= xr; ++x) {
      const double d = (sx * double(x) + sy) - W * zr[x];
      rhi = std::max(rhi, d);
      rlo = std::min(rlo, d);
    }
    hi = rhi, lo = rlo;
    // Compare the value that is returned, not its numerator against cutoff * W: the product
    // can round below the numerator while the quotient rounds back to exactly the cutoff, and
    // a caller would then take a partial scan for an exact error.
    return !(std::max(hi, -lo) / W > cutoff);
  });
  return std::max(hi, -lo) / W;
}

double LInfError::triangle(GridPoint a, GridPoint b, GridPoint c, double cutoff) const {
  if (orient2d(a, b, c) == 0) {
    double e = segment(a, b, cutoff);
    if (e <= cutoff) e = std::max(e, segment(b, c, cutoff));
    if (e <= cutoff) e = std::max(e, segment(a, c, cutoff));
    return e;
  }
  double e = 0.0;
  if (metric_ == ErrorMetric::Continuous) {
    e = segment(a, b, cutoff);
    if (e > cutoff) return e;
    e = std::max(e, segment(b, c, cutoff));
    if (e > cutoff) return e;
    e = std::max(e, segment(c, a, cutoff));
    if (e > cutoff) return e;
  }
  return std::max(e, samples_in_triangle(a, b, c, cutoff));
}

}  // namespace terralod::pm
