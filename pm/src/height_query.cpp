// Height queries on a Heightfield: inverse grid transform and the bilinear surface.
#include "terralod/pm/height_query.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

namespace terralod::pm {

std::pair<double, double> world_to_grid(const GridTransform& t, double x, double y) {
  const double det = t.determinant();
  assert(det != 0.0 && "world_to_grid: singular transform");
  const double dx = x - t.x0, dy = y - t.y0;
  return {(t.yr * dx - t.xr * dy) / det, (t.xc * dy - t.yc * dx) / det};
}

double bilinear_height(const Heightfield& hf, double x, double y) {
  assert(hf.width() >= 1 && hf.height() >= 1 && "bilinear_height: empty heightfield");
  const auto [gc, gr] = world_to_grid(hf.transform, x, y);
  const double c = std::clamp(gc, 0.0, double(hf.width() - 1)),
               r = std::clamp(gr, 0.0, double(hf.height() - 1));
  // The cell's lower corner; the last column/row belongs to the cell before it.
  const int c0 = std::max(0, std::min(int(c), hf.width() - 2)),
            r0 = std::max(0, std::min(int(r), hf.height() - 2));
  const int c1 = std::min(c0 + 1, hf.width() - 1), r1 = std::min(r0 + 1, hf.height() - 1);
  const double fc = c1 > c0 ? c - c0 : 0.0, fr = r1 > r0 ? r - r0 : 0.0;
  if (!hf.has_holes())
    return (1 - fr) * ((1 - fc) * hf.at(c0, r0) + fc * hf.at(c1, r0)) +
           fr * ((1 - fc) * hf.at(c0, r1) + fc * hf.at(c1, r1));
  const int cs[4] = {c0, c1, c0, c1}, rs[4] = {r0, r0, r1, r1};
  const double ws[4] = {(1 - fc) * (1 - fr), fc * (1 - fr), (1 - fc) * fr, fc * fr};
  double sum = 0, weight = 0;
  for (int i = 0; i < 4; ++i)
    if (hf.valid(cs[i], rs[i])) sum += ws[i] * hf.at(cs[i], rs[i]), weight += ws[i];
  // weight 0: the point lies on holes only (a valid corner with weight 0 does not reach it).
  return weight > 0 ? sum / weight : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace terralod::pm
