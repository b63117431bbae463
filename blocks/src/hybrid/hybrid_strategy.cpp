// The hybrid node strategy of the approximation tree built over a block database: a coarse grid
// of the node's domain with a TIN microstructure where the grid is worst, joined to the grid by
// the local convexification of seeds/hybrid-grid-tin-convexification.txt (HybridTerrain).
//
// Surface (see make_hybrid_strategy in tree_builder.hpp):
//   1. The grid strategy's (P+1) x (P+1) grid over the domain (cols, rows evenly spaced).
//   2. Every interior grid node (i, j) with its 2 x 2 cells is a candidate block. Its hybrid grid
//      step K is the gcd of the four cell sides (K >= 2, at most 4 x 4 hybrid cells in the block,
//      so the block's square hybrid cells fit the node's possibly rectangular cells exactly).
//      Candidates are ranked by the exact error of the grid's own triangles over the 2 x 2 cells
//      (the largest, then the sum of the four).
//   3. The best candidate gets a TIN microstructure: the greedy TIN (build_greedy_tin, at most
//      `tin_points` points) of the block less its border samples, so the TIN's boundary ring
//      crosses the hybrid grid lines through the centre and stays strictly inside the block.
//      HybridTerrain::build (one level, step K) classifies the block's cells, convexifies the uncovered part
//      of each PC cell and adds the corner triangles; extract(0) gives the block's triangles.
//   4. The cells outside the block keep the grid's two triangles, except that a cell sharing a
//      side with the block takes the block's hybrid grid nodes on that side into a fan (no
//      T-junction inside the node).
// Every point lands on a sample (the ring's sides are sample rows and columns, the hybrid grid
// lines are sample columns and rows, so their crossings are samples) and takes the sample's
// height, so the node meets NodeSurface's sample contract and pm::LInfError measures its exact
// error like any other node's. A candidate whose configuration HybridTerrain refuses (a void
// grid node, a ring it cannot encode) is skipped for the next; with none left, or a domain too
// small for an interior node, the surface is the grid alone: a hybrid surface whose cells are all
// NC (no microstructure), as the paper's model allows.
//
// Error: the node's error is the maximum over all its triangles, so the microstructure lowers it
// only when the worst block dominates (a peak, a cliff); the choice `auto` weighs that against
// the extra bytes like any other candidate.
#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <numeric>
#include <utility>
#include <vector>

#include "terralod/blocks/greedy_tin.hpp"
#include "terralod/blocks/hybrid/hybrid_terrain.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/linf_error.hpp"

namespace terralod::blocks {
namespace {

// Bounds of the block's extra points (see max_points): at most 4 x 4 hybrid cells in a block,
// so at most 5 x 5 or 9 x 3 hybrid nodes, 9 of them the node's grid nodes; the ring crosses each
// hybrid grid line strictly inside the block at most twice.
constexpr int kMaxHybridCells = 16;
constexpr std::size_t kMaxExtraNodes = 27 - 9;
constexpr std::size_t kMaxCrossings = 2 * (kMaxHybridCells / 2 - 1) + 2 * (2 - 1);

struct Block {
  int i = 0, j = 0;  // centre node: cols[i], rows[j]
  int step = 0;      // K
  double error = 0;  // of the grid's triangles over the block's 2 x 2 cells: the largest
  double sum = 0;    // ... and the sum of the four cells' errors (ranks ties)
};

class HybridStrategy final : public NodeStrategy {
 public:
  HybridStrategy(int patch, std::size_t tin_points, pm::ErrorMetric metric)
      : grid_(make_grid_strategy(patch)), p_(patch), t_(tin_points), metric_(metric) {
    assert(patch >= 1 && tin_points >= 4);
  }
  Strategy kind() const override { return Strategy::Hybrid; }
  int max_children() const override { return 4; }
  std::size_t max_points() const override {
    return std::size_t(p_ + 1) * std::size_t(p_ + 1) + kMaxExtraNodes + t_ + kMaxCrossings;
  }

  NodeSurface approximate(const pm::Heightfield& hf, SampleRect d) const override {
    NodeSurface grid = grid_->approximate(hf, d);
    for (const Block& b : candidates(hf, grid)) {
      NodeSurface s;
      if (with_block(hf, grid, b, s)) return s;
    }
    grid.cols.clear();  // the grid alone, as a hybrid surface (points + triangles)
    grid.rows.clear();
    return grid;
  }

 private:
  /// Interior nodes whose 2 x 2 cells take square hybrid cells, worst block first.
  std::vector<Block> candidates(const pm::Heightfield& hf, const NodeSurface& g) const {
    const int nc = int(g.cols.size()), nr = int(g.rows.size());
    std::vector<Block> out;
    if (nc < 3 || nr < 3) return out;
    const pm::LInfError err(hf, metric_);
    auto at = [&](int i, int j) {
      const auto& p = g.points[std::size_t(j) * std::size_t(nc) + std::size_t(i)];
      return pm::GridPoint{int(p[0]), int(p[1])};
    };
    std::vector<double> cell(std::size_t(nc - 1) * std::size_t(nr - 1));
    for (int j = 0; j + 1 < nr; ++j)
      for (int i = 0; i + 1 < nc; ++i)  // triangulate_grid's two triangles of the cell
        cell[std::size_t(j) * std::size_t(nc - 1) + std::size_t(i)] =
            std::max(err.triangle(at(i, j), at(i + 1, j), at(i + 1, j + 1)),
                     err.triangle(at(i, j), at(i + 1, j + 1), at(i, j + 1)));
    for (int j = 1; j + 1 < nr; ++j)
      for (int i = 1; i + 1 < nc; ++i) {
        const int a = g.cols[std::size_t(i)] - g.cols[std::size_t(i - 1)];
        const int b = g.cols[std::size_t(i + 1)] - g.cols[std::size_t(i)];
        const int c = g.rows[std::size_t(j)] - g.rows[std::size_t(j - 1)];
        const int e = g.rows[std::size_t(j + 1)] - g.rows[std::size_t(j)];
        const int k = std::gcd(std::gcd(a, b), std::gcd(c, e));
        if (k < 2 || ((a + b) / k) * ((c + e) / k) > kMaxHybridCells) continue;
        double worst = 0, sum = 0;
        for (int dj = -1; dj <= 0; ++dj)
          for (int di = -1; di <= 0; ++di) {
            const double e4 = cell[std::size_t(j + dj) * std::size_t(nc - 1) + std::size_t(i + di)];
            worst = std::max(worst, e4);
            sum += e4;
          }
        out.push_back({i, j, k, worst, sum});
      }
    std::stable_sort(out.begin(), out.end(), [](const Block& x, const Block& y) {
      return x.error != y.error ? x.error > y.error : x.sum > y.sum;
    });
    return out;
  }

  /// The grid with block b's microstructure; false when HybridTerrain refuses the block.
  bool with_block(const pm::Heightfield& hf, const NodeSurface& g, const Block& b, NodeSurface& s) const {
    const int nc = int(g.cols.size());
    const int c0 = g.cols[std::size_t(b.i - 1)], c1 = g.cols[std::size_t(b.i + 1)];
    const int r0 = g.rows[std::size_t(b.j - 1)], r1 = g.rows[std::size_t(b.j + 1)];
    // The microstructure: the greedy TIN of the block less its border samples.
    const SampleRect rect{c0 + 1, r0 + 1, c1 - 1, r1 - 1};
    TinOptions to;
    to.max_points = t_;
    to.metric = metric_;
    const TinSurface tin = build_greedy_tin(hf, rect, to);
    hybrid::TinMesh local;
    local.source = hf.source + ": hybrid node over samples (" + std::to_string(c0) + "," +
                   std::to_string(r0) + ")-(" + std::to_string(c1) + "," + std::to_string(r1) + ")";
    for (const auto& p : tin.points)
      local.points.push_back({double(p[0] - c0), double(p[1] - r0), hf.at(p[0], p[1])});
    local.triangles = tin.triangles;
    hybrid::HybridMesh m;
    try {
      const hybrid::HybridTerrain h = hybrid::HybridTerrain::build(
          c1 - c0 + 1, r1 - r0 + 1,
          [&](int col, int row) {
            return hf.valid(c0 + col, r0 + row) ? hf.at(c0 + col, r0 + row)
                                                : std::numeric_limits<double>::quiet_NaN();
          },
          local.source, local, {.grid_step = b.step, .levels = 1});
      m = h.extract(0, hybrid::Scheme::Triangles);
    } catch (const hybrid::HybridError&) {
      return false;  // a configuration the hybrid model does not encode: try the next block
    }
    // Points: the grid's, then the block's new ones (all on samples, at the samples' heights).
    s = {};
    std::map<std::pair<int, int>, std::uint32_t> index;
    auto add = [&](int col, int row) -> std::uint32_t {
      const auto [it, fresh] = index.try_emplace({col, row}, std::uint32_t(s.points.size()));
      if (fresh) s.points.push_back({double(col), double(row), hf.at(col, row)});
      return it->second;
    };
    for (const auto& p : g.points) add(int(p[0]), int(p[1]));
    std::vector<std::uint32_t> block_id(m.points.size());
    std::vector<pm::GridPoint> border;  // the block's points on its border, not grid nodes
    for (std::size_t v = 0; v < m.points.size(); ++v) {
      const double x = m.points[v][0], y = m.points[v][1];
      if (x != std::floor(x) || y != std::floor(y)) return false;  // cannot happen (see above); be safe
      const int col = c0 + int(x), row = r0 + int(y);
      if (!hf.valid(col, row)) return false;
      const bool grid_node = index.count({col, row}) != 0;
      block_id[v] = add(col, row);
      if (!grid_node && (col == c0 || col == c1 || row == r0 || row == r1)) border.push_back({col, row});
    }
    for (const auto& t : m.triangles) s.triangles.push_back({block_id[t[0]], block_id[t[1]], block_id[t[2]]});
    // The cells outside the block: two triangles, or a fan over the block's nodes on a shared side.
    const int nr = int(g.rows.size());
    for (int j = 0; j + 1 < nr; ++j)
      for (int i = 0; i + 1 < nc; ++i) {
        if ((i == b.i - 1 || i == b.i) && (j == b.j - 1 || j == b.j)) continue;
        const int x0 = g.cols[std::size_t(i)], x1 = g.cols[std::size_t(i + 1)];
        const int y0 = g.rows[std::size_t(j)], y1 = g.rows[std::size_t(j + 1)];
        // CCW in (col, row): (x0,y0) -> (x1,y0) -> (x1,y1) -> (x0,y1), with the block's nodes
        // strictly inside each side inserted in order along it.
        const std::array<pm::GridPoint, 4> corner{{{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}}};
        std::array<std::vector<pm::GridPoint>, 4> side;
        for (const pm::GridPoint& q : border) {
          if (q.y == y0 && q.x > x0 && q.x < x1) side[0].push_back(q);
          if (q.x == x1 && q.y > y0 && q.y < y1) side[1].push_back(q);
          if (q.y == y1 && q.x > x0 && q.x < x1) side[2].push_back(q);
          if (q.x == x0 && q.y > y0 && q.y < y1) side[3].push_back(q);
        }
        std::sort(side[0].begin(), side[0].end(), [](auto p, auto q) { return p.x < q.x; });
        std::sort(side[1].begin(), side[1].end(), [](auto p, auto q) { return p.y < q.y; });
        std::sort(side[2].begin(), side[2].end(), [](auto p, auto q) { return p.x > q.x; });
        std::sort(side[3].begin(), side[3].end(), [](auto p, auto q) { return p.y > q.y; });
        int apex = -1;  // a corner neither of whose sides (k-1, k) has inserted nodes
        for (int k = 0; k < 4 && apex < 0; ++k)
          if (side[std::size_t(k)].empty() && side[std::size_t((k + 3) % 4)].empty()) apex = k;
        if (apex < 0) return false;  // two opposite sides on the block: impossible for a 2 x 2 block
        std::vector<std::uint32_t> ring;
        for (int k = 0; k < 4; ++k) {
          const int c = (apex + k) % 4;
          ring.push_back(add(corner[std::size_t(c)].x, corner[std::size_t(c)].y));
          for (const pm::GridPoint& q : side[std::size_t(c)]) ring.push_back(add(q.x, q.y));
        }
        if (ring.size() == 4 && apex % 2 == 1) {  // keep triangulate_grid's diagonal (x0,y0)-(x1,y1)
          std::rotate(ring.begin(), ring.begin() + 1, ring.end());
        }
        for (std::size_t k = 1; k + 1 < ring.size(); ++k)
          s.triangles.push_back({ring[0], ring[k], ring[k + 1]});
      }
    // Drop the points no triangle uses (the grid nodes inside the block that the TIN covers).
    std::vector<std::uint32_t> renum(s.points.size(), UINT32_MAX);
    for (const auto& t : s.triangles)
      for (std::uint32_t v : t) renum[v] = 0;
    std::vector<std::array<double, 3>> used;
    for (std::size_t v = 0; v < s.points.size(); ++v)
      if (renum[v] == 0) {
        renum[v] = std::uint32_t(used.size());
        used.push_back(s.points[v]);
      }
    for (auto& t : s.triangles)
      for (std::uint32_t& v : t) v = renum[v];
    s.points = std::move(used);
    return s.points.size() <= max_points();
  }

  std::unique_ptr<NodeStrategy> grid_;
  int p_;
  std::size_t t_;
  pm::ErrorMetric metric_;
};

}  // namespace

std::unique_ptr<NodeStrategy> make_hybrid_strategy(int patch, std::size_t tin_points,
                                                   pm::ErrorMetric metric) {
  return std::make_unique<HybridStrategy>(patch, tin_points, metric);
}

}  // namespace terralod::blocks
