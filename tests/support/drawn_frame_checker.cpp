// Independent checker of a drawn frame (see drawn_frame_checker.hpp).
#include "drawn_frame_checker.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <set>
#include <sstream>

namespace terralod::test {

std::string FrameCheck::describe() const {
  std::ostringstream s;
  s << "max error " << max_error_px << " px (" << max_error_m << " m at col " << worst_col << ", row "
    << worst_row << "), samples in view " << samples_in_view << ", uncovered " << uncovered_in_view
    << ", triangles " << triangles << ", flipped " << flipped << ", doubled edges " << doubled_edges
    << ", T-junctions " << t_junctions << ", split vertices " << split_vertices << ", holes in view "
    << holes_in_view;
  return s.str();
}

FrameCheck check_drawn_frame(const pm::Heightfield& hf, const DrawnFrame& f, const pm::Camera& camera) {
  FrameCheck c;
  c.triangles = f.triangles.size();
  const ScreenProjector proj(camera);
  const std::uint64_t W = std::uint64_t(hf.width()), H = std::uint64_t(hf.height());
  std::vector<std::array<double, 3>> pos(f.samples.size());
  for (std::size_t v = 0; v < f.samples.size(); ++v)
    pos[v] = {double(f.samples[v] % W), double(f.samples[v] / W), f.z[v]};
  // Error and coverage at every sample.
  const SurfaceSamples surf = surface_at_samples(hf, pos, f.triangles);
  for (std::uint64_t row = 0; row < H; ++row)
    for (std::uint64_t col = 0; col < W; ++col) {
      const std::size_t i = std::size_t(row * W + col);
      if (!hf.valid(i)) continue;
      const auto [x, y] = hf.transform.to_world(double(col), double(row));
      const double h = hf[i];
      const bool in = proj.inside(x, y, h);
      c.samples_in_view += in;
      const double d = surf.height[i];
      if (std::isnan(d)) {
        c.uncovered_in_view += in;
        continue;
      }
      const double px = proj.vertical_segment_px(x, y, d, h);
      if (px > c.max_error_px) {
        c.max_error_px = px;
        c.max_error_m = std::abs(d - h);
        c.worst_col = int(col), c.worst_row = int(row);
      }
    }
  // Cracks.
  std::map<std::uint64_t, double> sample_z;
  for (std::size_t v = 0; v < f.samples.size(); ++v) {
    const auto [it, fresh] = sample_z.try_emplace(f.samples[v], f.z[v]);
    if (!fresh && it->second != f.z[v]) ++c.split_vertices;
  }
  std::map<std::pair<std::uint64_t, std::uint64_t>, int> edges;
  for (const auto& t : f.triangles) {
    std::int64_t p[3][2];
    for (int k = 0; k < 3; ++k)
      p[k][0] = std::int64_t(f.samples[t[k]] % W), p[k][1] = std::int64_t(f.samples[t[k]] / W);
    const std::int64_t o =
        (p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) - (p[1][1] - p[0][1]) * (p[2][0] - p[0][0]);
    if (o <= 0) ++c.flipped;
    for (int e = 0; e < 3; ++e) ++edges[{f.samples[t[e]], f.samples[t[(e + 1) % 3]]}];
  }
  const std::set<std::uint64_t> at(f.samples.begin(), f.samples.end());
  for (const auto& [e, n] : edges) {
    if (n > 1) ++c.doubled_edges;
    const bool back = edges.count({e.second, e.first}) != 0;
    const std::int64_t ax = std::int64_t(e.first % W), ay = std::int64_t(e.first / W);
    const std::int64_t bx = std::int64_t(e.second % W), by = std::int64_t(e.second / W);
    if (!back || e.first < e.second) {  // each undirected edge once
      const std::int64_t dx = bx - ax, dy = by - ay, g = std::gcd(std::abs(dx), std::abs(dy));
      for (std::int64_t k = 1; k < g; ++k)
        if (at.count(std::uint64_t(ay + dy / g * k) * W + std::uint64_t(ax + dx / g * k))) ++c.t_junctions;
    }
    if (back) continue;
    const bool terrain_border = (ax == bx && (ax == 0 || ax == std::int64_t(W) - 1)) ||
                                (ay == by && (ay == 0 || ay == std::int64_t(H) - 1));
    if (terrain_border) continue;
    // The border of a hole (a sample that is not valid beside an endpoint) is no crack: the
    // terrain ends there.
    auto beside_hole = [&](std::int64_t x, std::int64_t y) {
      for (std::int64_t j = std::max<std::int64_t>(0, y - 1); j <= std::min<std::int64_t>(H - 1, y + 1); ++j)
        for (std::int64_t i = std::max<std::int64_t>(0, x - 1); i <= std::min<std::int64_t>(W - 1, x + 1);
             ++i)
          if (!hf.valid(int(i), int(j))) return true;
      return false;
    };
    if (hf.has_holes() && (beside_hole(ax, ay) || beside_hole(bx, by))) continue;
    bool in_view = false;
    for (std::uint64_t s : {e.first, e.second}) {
      if (!hf.valid(std::size_t(s))) continue;
      const auto [x, y] = hf.transform.to_world(double(s % W), double(s / W));
      in_view = in_view || proj.inside(x, y, hf[std::size_t(s)]);
    }
    c.holes_in_view += in_view;
  }
  return c;
}

}  // namespace terralod::test
