// Node surface errors and domain z range over a DemSource, window by window (surface_scan.hpp).
//
// Why the maximum over windows is the whole-heightfield error bit for bit: surface_error is the
// maximum, over the surface's triangles, of pm::LInfError's terms (linf_error.hpp): for each
// sample of the closed triangle |plane numerator - W z| / W, for each crossing of an edge with a
// grid edge |lin - orig| / D (and, with holes, only valid samples and edges between valid
// samples: tin_error.hpp). LInfError over a window (GridWindow) computes the terms that lie in the
// window with the same formulas and rounding (the plane numerators are per row, the crossings'
// positions exact integers), and takes its maxima before the one monotonic division, so each
// window's value is the largest whole-grid term in it. The windows overlap by one sample row and
// column, so every sample, grid edge and cell diagonal of the domain lies entirely in one of them;
// the triangles lie in the domain. The maximum of the windows' values is therefore the maximum of
// all terms: surface_error's value. Corner heights come from the surface's points (z == the
// sample's height, NodeSurface's contract), so a corner outside a window needs no read.
#include "surface_scan.hpp"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <limits>

#include "terralod/pm/parallel.hpp"

namespace terralod::blocks::detail {
namespace {

/// Starts of windows of `size` samples over first .. last, each sharing its first sample with
/// the previous one's last.
std::vector<std::array<int, 2>> spans(int first, int last, int size) {
  std::vector<std::array<int, 2>> out;
  for (int a = first;; a += size - 1) {
    const int b = std::min(last, a + size - 1);
    out.push_back({a, b});
    if (b == last) break;
  }
  return out;
}

struct Triangle {
  pm::GridPoint a, b, c;
  std::array<double, 3> z;
  int x0, y0, x1, y1;  // bounding box
  std::size_t surface;
};

}  // namespace

std::vector<SampleRect> scan_windows(SampleRect domain, std::size_t window_samples) {
  assert(window_samples >= 4 && domain.col0 <= domain.col1 && domain.row0 <= domain.row1);
  window_samples = std::min(window_samples, std::size_t(1) << 62);  // side + 1 squared cannot overflow
  std::size_t side = std::size_t(std::sqrt(double(window_samples)));
  while (side * side > window_samples) --side;
  while ((side + 1) * (side + 1) <= window_samples) ++side;
  const int w = int(std::min<std::size_t>(std::size_t(domain.width()), side));
  const int h = int(std::min<std::size_t>(std::size_t(domain.height()),
                                          std::min<std::size_t>(window_samples / std::size_t(w), INT32_MAX)));
  std::vector<SampleRect> out;
  for (const auto& r : spans(domain.row0, domain.row1, h))
    for (const auto& c : spans(domain.col0, domain.col1, w))
      out.push_back(SampleRect{c[0], r[0], c[1], r[1]});
  return out;
}

SurfaceScan scan_surfaces(const DemSource& src, SampleRect domain,
                          std::span<const NodeSurface* const> surfaces, pm::ErrorMetric metric,
                          std::size_t window_samples, int threads) {
  assert(domain.col0 >= 0 && domain.row0 >= 0 && domain.col1 < src.grid().width &&
         domain.row1 < src.grid().height);
  std::vector<Triangle> tris;
  for (std::size_t i = 0; i < surfaces.size(); ++i) {
    const NodeSurface& s = *surfaces[i];
    for (const auto& t : s.triangles) {
      Triangle x;
      x.surface = i;
      pm::GridPoint* p[3] = {&x.a, &x.b, &x.c};
      for (int k = 0; k < 3; ++k) {
        const auto& q = s.points[t[std::size_t(k)]];
        *p[k] = pm::GridPoint{int(q[0]), int(q[1])};
        x.z[std::size_t(k)] = q[2];
        assert(domain.contains(p[k]->x, p[k]->y));
      }
      x.x0 = std::min({x.a.x, x.b.x, x.c.x}), x.x1 = std::max({x.a.x, x.b.x, x.c.x});
      x.y0 = std::min({x.a.y, x.b.y, x.c.y}), x.y1 = std::max({x.a.y, x.b.y, x.c.y});
      tris.push_back(x);
    }
  }
  const std::vector<SampleRect> windows = scan_windows(domain, window_samples);
  // Per window: the surfaces' errors, then its z range (+inf, -inf when it has no valid sample).
  const std::size_t n = surfaces.size(), stride = n + 2;
  std::vector<double> found(windows.size() * stride);
  pm::parallel_for(windows.size(), threads, [&](std::size_t w) {
    const SampleRect& r = windows[w];
    const pm::Heightfield hf = src.read(r);
    const pm::LInfError linf(hf, metric, {.origin = {r.col0, r.row0}, .skip_holes = true});
    double* out = found.data() + w * stride;
    for (const Triangle& t : tris)
      if (t.x0 <= r.col1 && t.x1 >= r.col0 && t.y0 <= r.row1 && t.y1 >= r.row0)
        out[t.surface] = std::max(out[t.surface], linf.triangle(t.a, t.b, t.c, t.z));
    double zlo = std::numeric_limits<double>::infinity(), zhi = -zlo;
    const std::vector<double>& z = hf.samples();
    for (std::size_t i = 0; i < z.size(); ++i)
      if (hf.valid(i)) zlo = std::min(zlo, z[i]), zhi = std::max(zhi, z[i]);
    out[n] = zlo, out[n + 1] = zhi;
  });
  SurfaceScan res;
  res.errors.assign(n, 0.0);
  double zlo = std::numeric_limits<double>::infinity(), zhi = -zlo;
  for (std::size_t w = 0; w < windows.size(); ++w) {
    const double* v = found.data() + w * stride;
    for (std::size_t i = 0; i < n; ++i) res.errors[i] = std::max(res.errors[i], v[i]);
    zlo = std::min(zlo, v[n]), zhi = std::max(zhi, v[n + 1]);
  }
  if (zlo > zhi) zlo = zhi = 0.0;
  res.zlo = zlo, res.zhi = zhi;
  return res;
}

}  // namespace terralod::blocks::detail
