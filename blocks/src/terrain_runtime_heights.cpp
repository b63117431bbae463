// Heights under a point of the terrain runtime (terrain_runtime.hpp): the drawn surface's, found
// through a bucket grid over the drawn triangles, and the highest sample of the smallest tree
// node there, known without loading anything.
#include <algorithm>
#include <cmath>
#include <limits>

#include "grid_triangle.hpp"
#include "terrain_runtime_internal.hpp"
#include "terralod/blocks/terrain_runtime.hpp"

namespace terralod::blocks {

double TerrainRuntime::max_height_at(double x, double y) const {
  auto [c, r] = grid_.to_grid(x, y);
  c = std::clamp(c, 0.0, double(grid_.grid_width() - 1));
  r = std::clamp(r, 0.0, double(grid_.grid_height() - 1));
  const TreeNode* n = &tree_.root();
  for (bool deeper = true; deeper;) {
    deeper = false;
    for (std::int64_t k : n->children) {
      const SampleRect& d = tree_.node(k).domain;
      if (c >= d.col0 && c <= d.col1 && r >= d.row0 && r <= d.row1) {
        n = &tree_.node(k);
        deeper = true;
        break;
      }
    }
  }
  return n->bbox.hi.z;
}

const TerrainRuntime::HeightIndex& TerrainRuntime::height_index() const {
  // A bucket grid over the drawn triangles' sample-space boxes, built on the first call after
  // an update: a query then tests the triangles of one bucket (ray marches call it often).
  HeightIndex& ix = height_index_;
  const std::uint64_t W = std::uint64_t(grid_.grid_width());
  auto corners = [&](std::size_t f, detail::Tri3& q) {
    const auto& t = mesh_.triangles[f];
    for (std::size_t k = 0; k < 3; ++k) {
      const std::uint64_t sm = mesh_.samples[t[k]];
      q[k] = {double(sm % W), double(sm / W), mesh_.positions[t[k]].z};
    }
  };
  if (ix.frame != frame_) {
    ix.frame = frame_;
    const int side = std::clamp(int(std::sqrt(double(mesh_.triangles.size()) / 4.0)), 1, 256);
    ix.nx = ix.ny = side;
    ix.cell_w = double(std::max(grid_.grid_width() - 1, 1)) / side;
    ix.cell_h = double(std::max(grid_.grid_height() - 1, 1)) / side;
    ix.start.assign(std::size_t(side) * side + 1, 0);
    std::vector<std::array<int, 4>> span(mesh_.triangles.size());
    for (std::size_t f = 0; f < mesh_.triangles.size(); ++f) {
      detail::Tri3 q;
      corners(f, q);
      auto cell = [&](double v, double w, int n) { return std::clamp(int(std::floor(v / w)), 0, n - 1); };
      span[f] = {cell(std::min({q[0][0], q[1][0], q[2][0]}), ix.cell_w, side),
                 cell(std::max({q[0][0], q[1][0], q[2][0]}), ix.cell_w, side),
                 cell(std::min({q[0][1], q[1][1], q[2][1]}), ix.cell_h, side),
                 cell(std::max({q[0][1], q[1][1], q[2][1]}), ix.cell_h, side)};
      for (int j = span[f][2]; j <= span[f][3]; ++j)
        for (int i = span[f][0]; i <= span[f][1]; ++i) ++ix.start[std::size_t(j) * side + i + 1];
    }
    for (std::size_t k = 1; k < ix.start.size(); ++k) ix.start[k] += ix.start[k - 1];
    ix.tris.resize(ix.start.back());
    std::vector<std::uint32_t> fill(ix.start.begin(), ix.start.end() - 1);
    for (std::size_t f = 0; f < mesh_.triangles.size(); ++f)
      for (int j = span[f][2]; j <= span[f][3]; ++j)
        for (int i = span[f][0]; i <= span[f][1]; ++i)
          ix.tris[fill[std::size_t(j) * side + i]++] = std::uint32_t(f);
  }
  return ix;
}

void TerrainRuntime::drawn_triangles_in(double x0, double y0, double x1, double y1,
                                        std::vector<std::uint32_t>& out) const {
  out.clear();
  const HeightIndex& ix = height_index();
  const auto [ca, ra] = grid_.to_grid(x0, y0);
  const auto [cb, rb] = grid_.to_grid(x1, y1);
  const double c0 = std::min(ca, cb), c1 = std::max(ca, cb), r0 = std::min(ra, rb), r1 = std::max(ra, rb);
  if (!(c1 >= 0 && r1 >= 0 && c0 <= grid_.grid_width() - 1 && r0 <= grid_.grid_height() - 1)) return;
  auto cell = [](double v, double w, int n) { return std::clamp(int(std::floor(v / w)), 0, n - 1); };
  const int i0 = cell(c0, ix.cell_w, ix.nx), i1 = cell(c1, ix.cell_w, ix.nx);
  const int j0 = cell(r0, ix.cell_h, ix.ny), j1 = cell(r1, ix.cell_h, ix.ny);
  for (int j = j0; j <= j1; ++j)
    for (int i = i0; i <= i1; ++i) {
      const std::size_t b = std::size_t(j) * ix.nx + i;
      out.insert(out.end(), ix.tris.begin() + ix.start[b], ix.tris.begin() + ix.start[b + 1]);
    }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
}

double TerrainRuntime::drawn_height(double x, double y) const {
  const HeightIndex& ix = height_index();
  const std::uint64_t W = std::uint64_t(grid_.grid_width());
  auto corners = [&](std::size_t f, detail::Tri3& q) {
    const auto& t = mesh_.triangles[f];
    for (std::size_t k = 0; k < 3; ++k) {
      const std::uint64_t sm = mesh_.samples[t[k]];
      q[k] = {double(sm % W), double(sm / W), mesh_.positions[t[k]].z};
    }
  };
  const auto [c, r] = grid_.to_grid(x, y);
  if (!(c >= 0 && r >= 0 && c <= grid_.grid_width() - 1 && r <= grid_.grid_height() - 1))
    return std::numeric_limits<double>::quiet_NaN();
  const int i = std::clamp(int(std::floor(c / ix.cell_w)), 0, ix.nx - 1);
  const int j = std::clamp(int(std::floor(r / ix.cell_h)), 0, ix.ny - 1);
  const std::size_t bucket = std::size_t(j) * ix.nx + i;
  for (std::uint32_t k = ix.start[bucket]; k < ix.start[bucket + 1]; ++k) {
    detail::Tri3 q;
    corners(ix.tris[k], q);
    if (detail::outside_box(q, c, r)) continue;
    const detail::Barycentric w = detail::barycentric(q, c, r);
    if (w.det == 0) continue;
    if (w.l1 >= -1e-12 && w.l2 >= -1e-12 && w.l0 >= -1e-12) return detail::plane_height(q, w);
  }
  return std::numeric_limits<double>::quiet_NaN();
}

}  // namespace terralod::blocks
