// The hybrid grid + TIN model's build (Boo, Amor, Doellner, "Unified hybrid terrain
// representation based on local convexifications", sections 2-5 and the appendix):
// HybridTerrain::build running the builder's steps (hybrid_builder.hpp) and its last step, the
// sub-cell trees and the check that the encoding decodes to the convexification built; with
// the TIN conversions between world and grid coordinates.
// Memory: O(TB vertices) per level while building, plus one byte per cell per level.
#include "terralod/blocks/hybrid/hybrid_terrain.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "hybrid_builder.hpp"
#include "hybrid_geometry.hpp"
#include "hybrid_internal.hpp"

namespace terralod::blocks::hybrid {

using detail::kScale;
using detail::LPoint;

std::string cell_name(int level, std::uint32_t cell, int cells_x) {
  return "level " + std::to_string(level) + " cell (" + std::to_string(cell % std::uint32_t(cells_x)) + "," +
         std::to_string(cell / std::uint32_t(cells_x)) + ")";
}

TinMesh tin_from_world(const pm::TriangleMeshData& world, const pm::GridTransform& t,
                       const std::string& source) {
  const double det = t.determinant();
  if (!(std::abs(det) > 0) || !std::isfinite(det))
    throw HybridError(source + ": grid transform is not invertible");
  TinMesh m;
  m.source = source;
  m.triangles = world.triangles;
  m.points.reserve(world.positions.size());
  for (const auto& p : world.positions) {
    const double dx = p[0] - t.x0, dy = p[1] - t.y0;
    // Inverse of [xc xr; yc yr].
    const double col = (t.yr * dx - t.xr * dy) / det, row = (-t.yc * dx + t.xc * dy) / det;
    m.points.push_back({col, row, p[2]});
  }
  return m;
}

TinMesh merge_tins(const std::vector<TinMesh>& tins) {
  TinMesh m;
  for (const TinMesh& t : tins) {
    const std::uint32_t base = std::uint32_t(m.points.size());
    m.points.insert(m.points.end(), t.points.begin(), t.points.end());
    for (auto tri : t.triangles) m.triangles.push_back({tri[0] + base, tri[1] + base, tri[2] + base});
    m.source += (m.source.empty() ? "" : "+") + t.source;
  }
  return m;
}

pm::TriangleMeshData to_world(const HybridMesh& mesh, const pm::GridTransform& t) {
  pm::TriangleMeshData w;
  w.positions.reserve(mesh.points.size());
  for (const auto& p : mesh.points) {
    auto [x, y] = t.to_world(p[0], p[1]);
    w.positions.push_back({x, y, p[2]});
  }
  w.triangles = mesh.triangles;
  if (t.determinant() < 0)
    for (auto& tri : w.triangles) std::swap(tri[1], tri[2]);
  return w;
}

PlanPoint HybridTerrain::tb_point(std::uint32_t t) const {
  const Vertex& v = vertices_.at(tb_.at(t));
  return {double(v.x) / kScale, double(v.y) / kScale};
}

// ---------------------------------------------------------------------------------------------
// Step 3 of the builder: the sub-cell trees and the verification.

void Builder::build_trees() {
  for (int l = 0; l < L; ++l) {
    LevelEncoding& enc = h.levels_[std::size_t(l)];
    enc.tree.clear();
    enc.tree_offset.assign(1, 0);
    for (const PcCell& pc : enc.vc) {
      if (l > 0) {
        std::vector<std::pair<int, std::uint32_t>> queue{{l, pc.cell}};
        for (std::size_t qi = 0; qi < queue.size(); ++qi) {
          const auto [ql, qc] = queue[qi];
          const LevelEncoding& up = h.levels_[std::size_t(ql)];
          const LevelEncoding& dn = h.levels_[std::size_t(ql - 1)];
          const std::uint32_t i = qc % std::uint32_t(up.cells_x), j = qc / std::uint32_t(up.cells_x);
          for (std::uint32_t q = 0; q < 4; ++q) {
            const std::uint32_t ci = 2 * i + (q & 1), cj = 2 * j + (q >> 1);
            const std::uint32_t child = cj * std::uint32_t(dn.cells_x) + ci;
            const CellClass cc = dn.gc[child];
            enc.tree.push_back(std::uint8_t(cc));
            if (cc == CellClass::PC && ql - 1 > 0) queue.push_back({ql - 1, child});
          }
        }
      }
      enc.tree_offset.push_back(std::uint32_t(enc.tree.size()));
    }
  }
}

void Builder::verify() {
  for (int l = 0; l < L; ++l) {
    const LevelEncoding& enc = h.levels_[std::size_t(l)];
    for (const PcCell& pc : enc.vc) {
      auto dec = h.decoded_fill(l, pc.cell), dir = h.direct_fill(l, pc.cell);
      auto canon = [](std::vector<std::array<std::uint32_t, 3>> v) {
        for (auto& t : v) std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
        std::sort(v.begin(), v.end());
        return v;
      };
      if (canon(dec) != canon(dir))
        throw HybridError(src + ": " + cell_name(l, pc.cell, enc.cells_x) +
                          ": the one-index connectivity cannot encode this level's convexification "
                          "(decoded " +
                          std::to_string(dec.size()) + " triangles, direct " + std::to_string(dir.size()) +
                          "); use fewer levels");
      const CellTessellation t = Extractor::tessellate(h, l, pc);
      double tri_area2 = 0, u_area2 = 0;
      auto pt = [&](std::uint32_t tb) { return TP(tb); };
      for (const auto& f : t.fill) tri_area2 += detail::area2({pt(f[0]), pt(f[1]), pt(f[2])});
      const std::int64_t cs = ks << l;
      const std::int64_t x0 = std::int64_t(pc.cell % std::uint32_t(enc.cells_x)) * cs;
      const std::int64_t y0 = std::int64_t(pc.cell / std::uint32_t(enc.cells_x)) * cs;
      for (const auto& c : t.corner_tris) {
        std::vector<LPoint> tri;
        for (const CellRef& r : c)
          tri.push_back(r.corner ? LPoint{x0 + ((r.id == 1 || r.id == 2) ? cs : 0), y0 + (r.id >= 2 ? cs : 0)}
                                 : pt(r.id));
        const double a = detail::area2(tri);
        if (!(a > 0))
          throw HybridError(src + ": " + cell_name(l, pc.cell, enc.cells_x) +
                            ": a corner triangle is flipped or degenerate");
        tri_area2 += a;
      }
      for (double a : t.uncovered_area2) u_area2 += a;
      if (std::abs(tri_area2 - u_area2) > 1e-9 * std::max(1.0, u_area2))
        throw HybridError(src + ": " + cell_name(l, pc.cell, enc.cells_x) +
                          ": convexification and corner triangles do not cover the uncovered area exactly "
                          "(unsupported configuration)");
      for (std::size_t k = 0; k < t.hulls.size(); ++k) {
        auto it = hulls_.find({l, pc.cell, int(k)});
        if (it == hulls_.end() || it->second != t.hulls[k])
          throw HybridError(src + ": " + cell_name(l, pc.cell, enc.cells_x) +
                            ": the decoded convex hull differs from the direct one; use fewer levels");
      }
    }
  }
}

// ---------------------------------------------------------------------------------------------

std::vector<std::array<std::uint32_t, 3>> HybridTerrain::direct_fill(int level, std::uint32_t cell) const {
  const LevelEncoding& enc = levels_.at(std::size_t(level));
  std::vector<std::array<std::uint32_t, 3>> out;
  for (const FillRecord& f : direct_) {
    if (f.level > level) continue;
    const int shift = level - f.level;
    const std::uint32_t fx = f.cell % std::uint32_t(levels_[std::size_t(f.level)].cells_x);
    const std::uint32_t fy = f.cell / std::uint32_t(levels_[std::size_t(f.level)].cells_x);
    if ((fy >> shift) * std::uint32_t(enc.cells_x) + (fx >> shift) == cell) out.push_back(f.tri);
  }
  return out;
}

HybridTerrain HybridTerrain::build(const pm::Heightfield& grid, const TinMesh& tin, const HybridOptions& o) {
  return build(
      grid.width(), grid.height(),
      [&](int col, int row) {
        return grid.valid(col, row) ? grid.at(col, row) : std::numeric_limits<double>::quiet_NaN();
      },
      grid.source, tin, o);
}

HybridTerrain HybridTerrain::build(int width, int height, const std::function<double(int, int)>& node_z,
                                   const std::string& source, const TinMesh& tin, const HybridOptions& o) {
  assert(o.grid_step >= 1 && o.levels >= 1 && o.levels <= 16);
  HybridTerrain h;
  Builder b(h);
  b.src = tin.source.empty() ? std::string("TIN") : tin.source;
  b.L = o.levels;
  h.step_ = o.grid_step;
  const int coarse = o.grid_step << (o.levels - 1);
  const int ncx = (width - 1) / coarse, ncy = (height - 1) / coarse;
  if (ncx < 1 || ncy < 1)
    throw HybridError(source + ": a " + std::to_string(width) + "x" + std::to_string(height) +
                      " grid holds no coarsest cell of " + std::to_string(coarse) + " samples (grid step " +
                      std::to_string(o.grid_step) + ", " + std::to_string(o.levels) + " levels)");
  h.domain_w_ = ncx * coarse;
  h.domain_h_ = ncy * coarse;
  const int nx = h.domain_w_ / o.grid_step + 1, ny = h.domain_h_ / o.grid_step + 1;
  h.grid_z_.resize(std::size_t(nx) * ny);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const double z = node_z(i * o.grid_step, j * o.grid_step);
      if (std::isnan(z))
        throw HybridError(source + ": grid node (" + std::to_string(i * o.grid_step) + "," +
                          std::to_string(j * o.grid_step) + ") is a void");
      h.grid_z_[std::size_t(j) * nx + i] = z;
    }
  b.ks = std::int64_t(o.grid_step) * kScale;
  b.load_tin(tin);
  h.levels_.resize(std::size_t(o.levels));
  for (int l = 0; l < o.levels; ++l) b.process_level(l);
  b.build_trees();
  b.verify();
  return h;
}

}  // namespace terralod::blocks::hybrid
