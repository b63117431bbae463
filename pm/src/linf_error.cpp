// Exact L-infinity error of grid-aligned triangles: rasterised samples plus grid-edge crossings.
#include "terralod/pm/linf_error.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <type_traits>
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

namespace {

std::int64_t ceil_div(std::int64_t a, std::int64_t b) { return -floor_div(-a, b); }

/// Narrows [lo, hi] to the integers t with L <= base + t * slope <= U (exact integer bounds).
void clip_steps(std::int64_t& lo, std::int64_t& hi, std::int64_t base, std::int64_t slope, std::int64_t L,
                std::int64_t U) {
  if (slope > 0) {
    lo = std::max(lo, ceil_div(L - base, slope));
    hi = std::min(hi, floor_div(U - base, slope));
  } else if (slope < 0) {
    lo = std::max(lo, ceil_div(base - U, -slope));
    hi = std::min(hi, floor_div(base - L, -slope));
  } else if (base < L || base > U) {
    hi = lo - 1;
  }
}

}  // namespace

double LInfError::segment(GridPoint p, GridPoint q, double cutoff) const {
  return segment(p, q, at(p), at(q), cutoff);
}

double LInfError::segment(GridPoint p, GridPoint q, double zp, double zq, double cutoff) const {
  const Heightfield& hf = *hf_;
  // In the heightfield's indices: the crossings' values do not depend on where the grid's
  // origin is (D, t and r are differences), and the window is 0 .. width-1, 0 .. height-1.
  p = {p.x - window_.origin.x, p.y - window_.origin.y};
  q = {q.x - window_.origin.x, q.y - window_.origin.y};
  const std::int64_t X1 = hf.width() - 1, Y1 = hf.height() - 1;
  const bool holes = window_.skip_holes && hf.has_holes();
  // A segment inside the heightfield (always, over the whole grid) needs no clipping.
  const bool inside = std::min(p.x, q.x) >= 0 && std::max(p.x, q.x) <= X1 && std::min(p.y, q.y) >= 0 &&
                      std::max(p.y, q.y) <= Y1;
  double worst = 0.0;
  // The crossings of a segment a -> b (heights za, zb) with one family of grid lines, D > 0
  // steps apart along it (and the samples on it): at step t = 1 .. D-1 it crosses a line
  // between the line's samples i and i + 1 (indices along the line), at i + r / D, where
  // i D + r = i0 D + t di with 0 <= r < D is tracked exactly. sample(t, i, k) is the sample
  // i + k (k = 0, 1) of the t-th line. Heights are compared multiplied by D (exact for
  // integers). The largest difference is divided once: division by D > 0 is monotonic in
  // floating point, so max(|d|) / D is the largest of the |d| / D, bit for bit.
  //
  // Only the steps whose crossing a + (t / D)(b - a) lies in the heightfield are walked, found
  // by arithmetic: the crossed grid edge's ends are the floors and ceilings of the crossing's
  // coordinates, so the edge lies in the (closed) window exactly when the crossing does. Each
  // step's value does not depend on where the walk starts (i and r are exact), so a window's
  // maximum is the maximum of the whole segment's terms in it.
  auto crossings = [&](GridPoint a, GridPoint b, std::int64_t D, std::int64_t i0, std::int64_t di, double za,
                       double zb, auto&& sample) {
    if (D <= 0) return;
    std::int64_t t0 = 1, t1 = D - 1;
    if (!inside) {
      clip_steps(t0, t1, std::int64_t(a.x) * D, std::int64_t(b.x) - a.x, 0, X1 * D);
      clip_steps(t0, t1, std::int64_t(a.y) * D, std::int64_t(b.y) - a.y, 0, Y1 * D);
      if (t0 > t1) return;
    }
    const std::int64_t qs = floor_div(di, D), rs = di - qs * D;
    std::int64_t i_start = i0, r_start = 0;  // the walk's state one step before t0
    if (t0 > 1) {
      const std::int64_t n = i0 * D + (t0 - 1) * di;
      i_start = floor_div(n, D), r_start = n - i_start * D;
    }
    auto walk = [&](auto skip_holes) {
      std::int64_t i = i_start, r = r_start;
      double most = 0.0;
      for (std::int64_t t = t0; t <= t1; ++t) {
        i += qs, r += rs;
        if (r >= D) r -= D, ++i;
        const GridPoint s0 = sample(t, i, 0);
        if constexpr (decltype(skip_holes)::value) {
          if (!hf.valid(s0.x, s0.y)) continue;
          if (r && !hf.valid(sample(t, i, 1).x, sample(t, i, 1).y)) continue;
        }
        double orig = hf.at(s0.x, s0.y) * double(D - r);
        if (r) orig += hf.at(sample(t, i, 1).x, sample(t, i, 1).y) * double(r);
        const double lin = za * double(D - t) + zb * double(t);
        most = std::max(most, std::abs(lin - orig));
      }
      return most;
    };
    const double most = holes ? walk(std::true_type{}) : walk(std::false_type{});
    worst = std::max(worst, most / double(D));
  };
  // Vertical lines x = a.x + t, their samples indexed by row (a.x <= b.x).
  auto vertical = [&](GridPoint a, GridPoint b, double za, double zb) {
    crossings(a, b, b.x - a.x, a.y, b.y - a.y, za, zb, [&](std::int64_t t, std::int64_t j, int k) {
      return GridPoint{int(a.x + t), int(j) + k};
    });
  };
  // Horizontal lines y = a.y + t, their samples indexed by column (a.y <= b.y).
  auto horizontal = [&](GridPoint a, GridPoint b, double za, double zb) {
    crossings(a, b, b.y - a.y, a.x, b.x - a.x, za, zb, [&](std::int64_t t, std::int64_t i, int k) {
      return GridPoint{int(i) + k, int(a.y + t)};
    });
  };
  // Diagonal lines x - y = a.x - a.y + t, the cells' diagonals from (i,j) to (i+1,j+1), their
  // samples indexed by column.
  auto diagonal = [&](GridPoint a, GridPoint b, double za, double zb) {
    const std::int64_t u0 = a.x - a.y;
    crossings(a, b, std::int64_t(b.x - b.y) - u0, a.x, b.x - a.x, za, zb,
              [&](std::int64_t t, std::int64_t i, int k) {
                return GridPoint{int(i) + k, int(i + k - (u0 + t))};
              });
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
  return samples_in_triangle(a, b, c, {at(a), at(b), at(c)}, cutoff);
}

double LInfError::samples_in_triangle(GridPoint a, GridPoint b, GridPoint c, const std::array<double, 3>& z,
                                      double cutoff) const {
  const Heightfield& hf = *hf_;
  // The samples inside, row by row (clipped to the heightfield), and the plane through the
  // corners as numerators over W = area2 (barycentric weights E_k / area2 from the edge
  // functions; grid_triangle.hpp). ccw swaps b and c when clockwise, and their heights with them.
  const bool swapped = orient2d(a, b, c) < 0;
  const GridTriangle t = GridTriangle::ccw(a, b, c);
  const double Z[3] = {z[0], swapped ? z[2] : z[1], swapped ? z[1] : z[2]};
  const double sx = t.plane_x(Z);
  const double W = double(t.area2);
  const int width = hf.width(), ox = window_.origin.x, oy = window_.origin.y;
  const double* zrow0 = hf.samples().data();
  const std::uint8_t* mrow0 = window_.skip_holes && hf.has_holes() ? hf.mask().data() : nullptr;
  double hi = 0.0, lo = 0.0;  // max and min of numerator(x) - W z, numerator space
  t.for_each_span(ox, oy, ox + hf.width() - 1, oy + hf.height() - 1,
                  [&](int y, std::int64_t xl, std::int64_t xr) {
                    const double sy = t.plane_y(Z, y);
                    const std::size_t row = std::size_t(y - oy) * width;
                    const double* zr = zrow0 + row;
                    double rhi = hi, rlo = lo;
                    if (!mrow0) {
                      for (std::int64_t x = xl; x <= xr; ++x) {
                        const double d = (sx * double(x) + sy) - W * zr[x - ox];
                        rhi = std::max(rhi, d);
                        rlo = std::min(rlo, d);
                      }
                    } else {
                      const std::uint8_t* mr = mrow0 + row;
                      for (std::int64_t x = xl; x <= xr; ++x) {
                        if (!mr[x - ox]) continue;
                        const double d = (sx * double(x) + sy) - W * zr[x - ox];
                        rhi = std::max(rhi, d);
                        rlo = std::min(rlo, d);
                      }
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
  return triangle(a, b, c, {at(a), at(b), at(c)}, cutoff);
}

double LInfError::triangle(GridPoint a, GridPoint b, GridPoint c, const std::array<double, 3>& z,
                           double cutoff) const {
  if (orient2d(a, b, c) == 0) {
    double e = segment(a, b, z[0], z[1], cutoff);
    if (e <= cutoff) e = std::max(e, segment(b, c, z[1], z[2], cutoff));
    if (e <= cutoff) e = std::max(e, segment(a, c, z[0], z[2], cutoff));
    return e;
  }
  double e = 0.0;
  if (metric_ == ErrorMetric::Continuous) {
    e = segment(a, b, z[0], z[1], cutoff);
    if (e > cutoff) return e;
    e = std::max(e, segment(b, c, z[1], z[2], cutoff));
    if (e > cutoff) return e;
    e = std::max(e, segment(c, a, z[2], z[0], cutoff));
    if (e > cutoff) return e;
  }
  return std::max(e, samples_in_triangle(a, b, c, z, cutoff));
}

}  // namespace terralod::pm
