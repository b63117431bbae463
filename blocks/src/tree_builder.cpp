// Approximation-tree builder (seeds/approximation-tree.txt, sections 3.1-3.2 and 6: one strategy
// interface, recursive subdivision). The block-database build is database_build.cpp. Memory: see
// tree_builder.hpp.
#include "terralod/blocks/tree_builder.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

#include "surface_scan.hpp"
#include "terralod/blocks/greedy_tin.hpp"
#include "terralod/pm/linf_error.hpp"
#include "terralod/pm/parallel.hpp"
#include "tin_error.hpp"

namespace terralod::blocks {
namespace {

pm::GridPoint gp(const std::array<double, 3>& p) { return {int(p[0]), int(p[1])}; }

NodeSurface surface_from_grid(const pm::Heightfield& hf, std::vector<int> cols, std::vector<int> rows) {
  NodeSurface s;
  s.cols = std::move(cols);
  s.rows = std::move(rows);
  s.points.reserve(s.cols.size() * s.rows.size());
  for (int r : s.rows)
    for (int c : s.cols) s.points.push_back({double(c), double(r), hf.at(c, r)});
  triangulate_grid(s);
  return s;
}

NodeSurface surface_from_tin(const pm::Heightfield& hf, const TinSurface& t) {
  NodeSurface s;
  s.points.reserve(t.points.size());
  for (const auto& p : t.points) s.points.push_back({double(p[0]), double(p[1]), hf.at(p[0], p[1])});
  s.triangles = t.triangles;
  return s;
}

/// Evenly spaced sample indices from a to b (inclusive), at most steps + 1 of them.
std::vector<int> even_samples(int a, int b, int steps) {
  std::vector<int> v;
  const int cells = b - a;
  const int n = std::min(steps, cells);
  for (int k = 0; k <= n; ++k) {
    const int x = a + int((std::int64_t(k) * cells + n / 2) / n);
    if (v.empty() || v.back() != x) v.push_back(x);
  }
  return v;
}

class GridStrategy final : public NodeStrategy {
 public:
  explicit GridStrategy(int patch) : p_(patch) { assert(patch >= 1); }
  Strategy kind() const override { return Strategy::Grid; }
  int max_children() const override { return 4; }
  std::size_t max_points() const override { return std::size_t(p_ + 1) * std::size_t(p_ + 1); }
  NodeSurface approximate(const pm::Heightfield& hf, SampleRect d) const override {
    return surface_from_grid(hf, even_samples(d.col0, d.col1, p_), even_samples(d.row0, d.row1, p_));
  }

 private:
  int p_;
};

// The strategies whose surface is chosen greedily by error within a budget of s points (TIN,
// non-regular grid): binary splits, and the options of a point budget with no error target.
class PointBudgetStrategy : public NodeStrategy {
 public:
  PointBudgetStrategy(std::size_t s, pm::ErrorMetric m) : s_(s), metric_(m) { assert(s >= 4); }
  int max_children() const override { return 2; }
  std::size_t max_points() const override { return s_; }

 protected:
  /// TinOptions or NonRegularGridOptions: at most s points, error as small as they allow.
  template <class Options>
  Options budget() const {
    Options o;
    o.max_error = 0.0;
    o.max_points = s_;
    o.metric = metric_;
    return o;
  }

 private:
  std::size_t s_;
  pm::ErrorMetric metric_;
};

class TinStrategy final : public PointBudgetStrategy {
 public:
  using PointBudgetStrategy::PointBudgetStrategy;
  Strategy kind() const override { return Strategy::Tin; }
  NodeSurface approximate(const pm::Heightfield& hf, SampleRect d) const override {
    return surface_from_tin(hf, build_greedy_tin(hf, d, budget<TinOptions>()));
  }
};

class NonRegularStrategy final : public PointBudgetStrategy {
 public:
  using PointBudgetStrategy::PointBudgetStrategy;
  Strategy kind() const override { return Strategy::NonRegularGrid; }
  NodeSurface approximate(const pm::Heightfield& hf, SampleRect d) const override {
    const NonRegularGrid g = build_nonregular_grid(hf, d, budget<NonRegularGridOptions>());
    return surface_from_grid(hf, g.cols, g.rows);
  }
};

/// Largest power of two strictly below n (n >= 2).
int pow2_below(int n) {
  int p = 1;
  while (p * 2 < n) p *= 2;
  return p;
}

struct Pending {
  std::int64_t parent = -1;
  int level = 0;
  SampleRect domain;
  int bc0 = 0, br0 = 0, bc1 = 0, br1 = 0;  // block range (inclusive)
};

struct Built {
  TreeNode node;
  bool split = false;
};

/// The node's box: its domain's corners in the world frame, z from the scan of its samples.
pm::Box domain_box(const DemGrid& g, SampleRect d, double zlo, double zhi) {
  pm::Box b;
  b.lo = {std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(), zlo};
  b.hi = {-std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(), zhi};
  for (int c : {d.col0, d.col1})
    for (int r : {d.row0, d.row1}) {
      const auto [x, y] = g.transform.to_world(c, r);
      b.lo.x = std::min(b.lo.x, x), b.hi.x = std::max(b.hi.x, x);
      b.lo.y = std::min(b.lo.y, y), b.hi.y = std::max(b.hi.y, y);
    }
  return b;
}

/// What a node's strategy sees of its domain: hf(i, j) is the sample (cols[i], rows[j]). Domains
/// of at most kNodeSamples samples are read whole (cols and rows every sample); larger ones (the
/// levels above a few thousand blocks) as a lattice every `stride` samples, a power of two, plus
/// their last column and row, read one row at a time, so that no node ever holds more than about
/// kNodeSamples samples whatever the DEM's size. The strategies choose their points on it; the
/// node's error is then measured exactly over every sample of the domain (scan_surfaces).
constexpr std::size_t kNodeSamples = std::size_t(513) * 513;
/// Window of the exact error scan, samples (a 513 x 513 square: 2 MiB of doubles).
constexpr std::size_t kScanWindow = std::size_t(513) * 513;

struct NodeSamples {
  pm::Heightfield hf;
  std::vector<int> cols, rows;
};

std::vector<int> lattice(int a, int b, int stride) {
  std::vector<int> v;
  for (std::int64_t x = a; x < b; x += stride) v.push_back(int(x));
  v.push_back(b);
  return v;
}

NodeSamples node_samples(const DemSource& src, SampleRect d) {
  NodeSamples n;
  int stride = 1;
  while (std::size_t((d.width() - 2) / stride + 2) * std::size_t((d.height() - 2) / stride + 2) >
         kNodeSamples)
    stride *= 2;
  if (stride == 1) {
    n.hf = src.read(d);
    n.cols = lattice(d.col0, d.col1, 1);
    n.rows = lattice(d.row0, d.row1, 1);
    return n;
  }
  n.cols = lattice(d.col0, d.col1, stride);
  n.rows = lattice(d.row0, d.row1, stride);
  n.hf = pm::Heightfield(int(n.cols.size()), int(n.rows.size()));
  std::vector<std::uint8_t> mask;
  for (std::size_t j = 0; j < n.rows.size(); ++j) {
    const pm::Heightfield row = src.read(SampleRect{d.col0, n.rows[j], d.col1, n.rows[j]});
    if (row.has_holes() && mask.empty()) mask.assign(n.hf.size(), 1);
    for (std::size_t i = 0; i < n.cols.size(); ++i) {
      const int c = n.cols[i] - d.col0;
      n.hf.at(int(i), int(j)) = row.at(c, 0);
      if (!row.valid(c, 0)) mask[j * n.cols.size() + i] = 0;
    }
  }
  if (!mask.empty()) n.hf.set_mask(std::move(mask));
  return n;
}

/// `s`, made on ns.hf, in whole-grid samples. A lattice can map a TIN's triangle to the other
/// orientation (its last column and row are closer than the stride); then false, and the caller
/// takes another surface.
bool to_grid(NodeSurface& s, const NodeSamples& ns) {
  std::vector<std::array<double, 3>> mapped = s.points;
  for (auto& p : mapped) p[0] = ns.cols[std::size_t(p[0])], p[1] = ns.rows[std::size_t(p[1])];
  for (const auto& t : s.triangles) {
    const auto o = [&](const std::vector<std::array<double, 3>>& q) {
      return pm::orient2d(gp(q[t[0]]), gp(q[t[1]]), gp(q[t[2]]));
    };
    const std::int64_t before = o(s.points), after = o(mapped);
    if ((before > 0) != (after > 0) || (before < 0) != (after < 0)) return false;
  }
  s.points = std::move(mapped);
  for (int& c : s.cols) c = ns.cols[std::size_t(c)];
  for (int& r : s.rows) r = ns.rows[std::size_t(r)];
  return true;
}

std::vector<Pending> split(const Pending& p, int children_max, const BlockLayout& layout) {
  std::vector<Pending> out;
  const bool multi = p.bc1 > p.bc0 || p.br1 > p.br0;
  auto child = [&](int bc0, int br0, int bc1, int br1, SampleRect d) {
    Pending c;
    c.level = p.level + 1;
    c.bc0 = bc0, c.br0 = br0, c.bc1 = bc1, c.br1 = br1;
    c.domain = d;
    out.push_back(c);
  };
  if (multi) {
    const int nbx = p.bc1 - p.bc0 + 1, nby = p.br1 - p.br0 + 1;
    bool cut_x = nbx > 1, cut_y = nby > 1;
    if (children_max == 2 && cut_x && cut_y) (p.domain.width() >= p.domain.height() ? cut_y : cut_x) = false;
    std::vector<std::array<int, 2>> xs{{p.bc0, p.bc1}}, ys{{p.br0, p.br1}};
    if (cut_x) xs = {{p.bc0, p.bc0 + pow2_below(nbx) - 1}, {p.bc0 + pow2_below(nbx), p.bc1}};
    if (cut_y) ys = {{p.br0, p.br0 + pow2_below(nby) - 1}, {p.br0 + pow2_below(nby), p.br1}};
    for (const auto& y : ys)
      for (const auto& x : xs) child(x[0], y[0], x[1], y[1], layout.rect(x[0], y[0], x[1], y[1]));
    return out;
  }
  const int cw = p.domain.width() - 1, ch = p.domain.height() - 1;
  bool cut_x = cw >= 2, cut_y = ch >= 2;
  if (children_max == 2 && cut_x && cut_y) (cw >= ch ? cut_y : cut_x) = false;
  if (!cut_x && !cut_y) return out;
  const SampleRect& d = p.domain;
  std::vector<std::array<int, 2>> xs{{d.col0, d.col1}}, ys{{d.row0, d.row1}};
  if (cut_x) xs = {{d.col0, d.col0 + cw / 2}, {d.col0 + cw / 2, d.col1}};
  if (cut_y) ys = {{d.row0, d.row0 + ch / 2}, {d.row0 + ch / 2, d.row1}};
  for (const auto& y : ys)
    for (const auto& x : xs) child(p.bc0, p.br0, p.bc1, p.br1, SampleRect{x[0], y[0], x[1], y[1]});
  return out;
}

using pm::parallel_for;

}  // namespace

std::unique_ptr<NodeStrategy> make_grid_strategy(int patch) { return std::make_unique<GridStrategy>(patch); }
std::unique_ptr<NodeStrategy> make_tin_strategy(std::size_t s, pm::ErrorMetric m) {
  return std::make_unique<TinStrategy>(s, m);
}
std::unique_ptr<NodeStrategy> make_nonregular_strategy(std::size_t s, pm::ErrorMetric m) {
  return std::make_unique<NonRegularStrategy>(s, m);
}

double surface_error(const pm::Heightfield& hf, const NodeSurface& s, pm::ErrorMetric metric) {
  const pm::LInfError err(hf, metric);
  double worst = 0.0;
  for (const auto& t : s.triangles)
    worst = std::max(worst, detail::triangle_error(err, hf, metric, gp(s.points[t[0]]), gp(s.points[t[1]]),
                                                   gp(s.points[t[2]])));
  return worst;
}

const char* strategy_choice_name(StrategyChoice c) {
  switch (c) {
    case StrategyChoice::Grid:
      return "grid";
    case StrategyChoice::Tin:
      return "tin";
    case StrategyChoice::NonRegularGrid:
      return "nonregular";
    case StrategyChoice::Hybrid:
      return "hybrid";
    case StrategyChoice::Auto:
      return "auto";
  }
  return "unknown";
}

StrategyChoice parse_strategy_choice(const std::string& name) {
  for (StrategyChoice c : {StrategyChoice::Grid, StrategyChoice::Tin, StrategyChoice::NonRegularGrid,
                           StrategyChoice::Hybrid, StrategyChoice::Auto})
    if (name == strategy_choice_name(c)) return c;
  throw std::invalid_argument("unknown strategy '" + name + "' (grid, tin, nonregular, hybrid or auto)");
}

ApproximationTree build_tree(const pm::Heightfield& hf, const BlockLayout& layout,
                             const TreeBuildOptions& opt, std::span<const double> block_errors,
                             const std::function<void(double)>& progress) {
  return build_tree(*heightfield_source(hf), layout, opt, block_errors, progress);
}

ApproximationTree build_tree(const DemSource& src, const BlockLayout& layout, const TreeBuildOptions& opt,
                             std::span<const double> block_errors,
                             const std::function<void(double)>& progress) {
  assert(!opt.levels.empty() && opt.patch >= 1 && opt.max_points >= 4 && opt.leaf_error >= 0.0);
  assert(layout.grid_width == src.grid().width && layout.grid_height == src.grid().height);
  assert(!opt.pm_leaves || block_errors.size() == layout.count());
  const auto grid = make_grid_strategy(opt.patch);
  const auto tin = make_tin_strategy(opt.max_points, opt.metric);
  const auto nonreg = make_nonregular_strategy(opt.max_points, opt.metric);
  const auto hybrid = make_hybrid_strategy(opt.patch, opt.max_points, opt.metric);
  auto strategy_of = [&](StrategyChoice c) -> const NodeStrategy* {
    switch (c) {
      case StrategyChoice::Grid:
        return grid.get();
      case StrategyChoice::Tin:
        return tin.get();
      case StrategyChoice::NonRegularGrid:
        return nonreg.get();
      case StrategyChoice::Hybrid:
        return hybrid.get();
      case StrategyChoice::Auto:
        return nullptr;
    }
    return nullptr;
  };

  ApproximationTree::Parameters params;
  params.patch = opt.patch;
  params.metric = opt.metric;
  const DemGrid& g = src.grid();
  params.transform = g.transform;
  params.grid_width = g.width;
  params.grid_height = g.height;
  params.max_points = 0;
  params.max_children = 0;
  for (StrategyChoice c : opt.levels) {
    const std::vector<const NodeStrategy*> used =
        c == StrategyChoice::Auto
            ? std::vector<const NodeStrategy*>{grid.get(), tin.get(), nonreg.get(), hybrid.get()}
            : std::vector<const NodeStrategy*>{strategy_of(c)};
    for (const NodeStrategy* s : used) {
      params.max_points = std::max(params.max_points, s->max_points());
      params.max_children = std::max(params.max_children, s->max_children());
    }
  }

  std::vector<TreeNode> nodes;
  std::vector<Pending> level{Pending{-1, 0, layout.rect(0, 0, layout.blocks_x - 1, layout.blocks_y - 1), 0, 0,
                                     layout.blocks_x - 1, layout.blocks_y - 1}};
  const double total_area = double(g.width - 1) * double(g.height - 1);
  double done_area = 0.0;
  while (!level.empty()) {
    std::vector<Built> built(level.size());
    parallel_for(level.size(), opt.threads, [&](std::size_t i) {
      const Pending& p = level[i];
      Built& b = built[i];
      TreeNode& n = b.node;
      n.parent = p.parent;
      n.level = p.level;
      n.domain = p.domain;
      const bool single_block = p.bc0 == p.bc1 && p.br0 == p.br1;
      if (opt.pm_leaves && single_block) {
        n.strategy = Strategy::PmBlock;
        n.block = BlockKey{p.bc0, p.br0};
        n.error = block_errors[std::size_t(p.bc0) * std::size_t(layout.blocks_y) + std::size_t(p.br0)];
        const detail::SurfaceScan z = detail::scan_surfaces(src, p.domain, {}, opt.metric, kScanWindow);
        n.bbox = domain_box(g, p.domain, z.zlo, z.zhi);
        return;
      }
      const StrategyChoice choice =
          opt.levels[std::min<std::size_t>(std::size_t(p.level), opt.levels.size() - 1)];
      const std::vector<const NodeStrategy*> tried =
          choice == StrategyChoice::Auto
              ? std::vector<const NodeStrategy*>{grid.get(), nonreg.get(), tin.get(), hybrid.get()}
              : std::vector<const NodeStrategy*>{strategy_of(choice)};
      // Every candidate's surface on the node's samples, then all their exact errors in one scan.
      const NodeSamples ns = node_samples(src, p.domain);
      const SampleRect whole{0, 0, ns.hf.width() - 1, ns.hf.height() - 1};
      std::vector<TreeNode> cands(tried.size(), n);
      std::vector<const NodeSurface*> surfaces;
      for (std::size_t k = 0; k < tried.size(); ++k) {
        cands[k].strategy = tried[k]->kind();
        cands[k].surface = tried[k]->approximate(ns.hf, whole);
        if (!to_grid(cands[k].surface, ns)) {  // a lattice flipped a triangle: the grid's never flip
          cands[k].strategy = Strategy::Grid;
          cands[k].surface = grid->approximate(ns.hf, whole);
          to_grid(cands[k].surface, ns);
        }
        surfaces.push_back(&cands[k].surface);
      }
      const detail::SurfaceScan scan =
          detail::scan_surfaces(src, p.domain, surfaces, opt.metric, kScanWindow);
      // Error per byte: keep the candidate with the smallest error x bytes (ties: fewer bytes).
      double best_score = std::numeric_limits<double>::infinity();
      std::size_t best_bytes = 0, best = 0;
      for (std::size_t k = 0; k < cands.size(); ++k) {
        cands[k].error = scan.errors[k];
        const std::size_t bytes = encoded_node_bytes(cands[k]);
        const double score = cands[k].error * double(bytes);
        if (k == 0 || score < best_score || (score == best_score && bytes < best_bytes))
          best_score = score, best_bytes = bytes, best = k;
      }
      n = std::move(cands[best]);
      n.bbox = domain_box(g, p.domain, scan.zlo, scan.zhi);
      b.split = opt.pm_leaves || n.error > opt.leaf_error;
    });
    std::vector<Pending> next;
    for (std::size_t i = 0; i < level.size(); ++i) {
      TreeNode& n = built[i].node;
      n.id = std::int64_t(nodes.size());
      if (n.parent >= 0) nodes[std::size_t(n.parent)].children.push_back(n.id);
      std::vector<Pending> kids;
      if (built[i].split) {
        const int d = n.strategy == Strategy::Grid || n.strategy == Strategy::Hybrid ? 4 : 2;
        kids = split(level[i], d, layout);
      }
      if (kids.empty()) done_area += double(n.domain.width() - 1) * double(n.domain.height() - 1);
      for (Pending& k : kids) {
        k.parent = n.id;
        next.push_back(k);
      }
      nodes.push_back(std::move(n));
    }
    if (progress) progress(std::min(1.0, done_area / total_area));
    level = std::move(next);
  }
  return ApproximationTree(std::move(params), std::move(nodes));
}

}  // namespace terralod::blocks
