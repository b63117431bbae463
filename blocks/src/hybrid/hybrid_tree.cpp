// The hybrid node strategy of the approximation tree (seeds/approximation-tree.txt section 3 and
// seeds/hybrid-grid-tin-convexification.txt): grid-only quadtree groups above per-cell hybrid
// level chains, exact node errors, and the crack-free union of a selection (cluster closure +
// extract_mixed's T-junction removal). Memory: see hybrid_tree.hpp.
#include "terralod/blocks/hybrid/hybrid_tree.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <functional>
#include <limits>
#include <numeric>
#include <unordered_map>

#include "hybrid_internal.hpp"
#include "terralod/pm/linf_error.hpp"

namespace terralod::blocks::hybrid {

using detail::kScale;
using detail::LPoint;

namespace {

std::uint64_t key(std::int64_t x, std::int64_t y) { return (std::uint64_t(x) << 32) ^ std::uint64_t(y); }
std::int64_t lattice(double v) { return std::llround(v * double(kScale)); }

double orient2(const std::array<double, 3>& a, const std::array<double, 3>& b, double px, double py) {
  return (b[0] - a[0]) * (py - a[1]) - (b[1] - a[1]) * (px - a[0]);
}

/// Coarsest cell holding the centroid of a triangle given in lattice units.
std::size_t owner_cell(const LPoint& a, const LPoint& b, const LPoint& c, std::int64_t cs_l, int nx, int ny) {
  const double cx = (double(a.x) + double(b.x) + double(c.x)) / 3.0,
               cy = (double(a.y) + double(b.y) + double(c.y)) / 3.0;
  const int i = std::clamp(int(std::floor(cx / double(cs_l))), 0, nx - 1);
  const int j = std::clamp(int(std::floor(cy / double(cs_l))), 0, ny - 1);
  return std::size_t(j) * std::size_t(nx) + std::size_t(i);
}

double surface_error(const pm::Heightfield& dem, const NodeSurface& s) {
  double e = 0;
  for (const auto& t : s.triangles)
    e = std::max(e, triangle_error(dem, s.points[t[0]], s.points[t[1]], s.points[t[2]]));
  return e;
}

pm::Box node_box(const pm::Heightfield& dem, const SampleRect& d, const NodeSurface& s) {
  double c0 = d.col0, c1 = d.col1, r0 = d.row0, r1 = d.row1;
  double zlo = std::numeric_limits<double>::infinity(), zhi = -zlo;
  for (int r = d.row0; r <= d.row1; ++r)
    for (int c = d.col0; c <= d.col1; ++c)
      if (dem.valid(c, r)) zlo = std::min(zlo, dem.at(c, r)), zhi = std::max(zhi, dem.at(c, r));
  for (const auto& p : s.points) {
    c0 = std::min(c0, p[0]), c1 = std::max(c1, p[0]), r0 = std::min(r0, p[1]), r1 = std::max(r1, p[1]);
    zlo = std::min(zlo, p[2]), zhi = std::max(zhi, p[2]);
  }
  pm::Box b;
  b.lo = {std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(), zlo};
  b.hi = {-b.lo.x, -b.lo.y, zhi};
  for (double c : {c0, c1})
    for (double r : {r0, r1}) {
      const auto [x, y] = dem.transform.to_world(c, r);
      b.lo.x = std::min(b.lo.x, x), b.lo.y = std::min(b.lo.y, y);
      b.hi.x = std::max(b.hi.x, x), b.hi.y = std::max(b.hi.y, y);
    }
  return b;
}

struct Pending {
  bool hybrid = false;
  int i0 = 0, j0 = 0, g = 1;  ///< group: first coarsest cell and size; hybrid: the cell (i0, j0)
  int level = 0;              ///< hybrid: grid level
  std::int64_t parent = -1;
  int depth = 0;
};

}  // namespace

double triangle_error(const pm::Heightfield& dem, const std::array<double, 3>& a,
                      const std::array<double, 3>& b, const std::array<double, 3>& c) {
  const pm::LInfError surf(dem, pm::ErrorMetric::Continuous);
  const double d = orient2(a, b, c[0], c[1]);
  assert(d != 0);
  double worst = 0;
  for (const auto* p : {&a, &b, &c})
    worst = std::max(worst, std::abs((*p)[2] - surf.surface_height((*p)[0], (*p)[1])));
  // Samples inside the closed triangle.
  const double x0 = std::min({a[0], b[0], c[0]}), x1 = std::max({a[0], b[0], c[0]});
  const double y0 = std::min({a[1], b[1], c[1]}), y1 = std::max({a[1], b[1], c[1]});
  for (int r = int(std::ceil(y0)); r <= int(std::floor(y1)); ++r)
    for (int col = int(std::ceil(x0)); col <= int(std::floor(x1)); ++col) {
      const double wa = orient2(b, c, col, r) / d, wb = orient2(c, a, col, r) / d,
                   wc = orient2(a, b, col, r) / d;
      if (wa < -1e-12 || wb < -1e-12 || wc < -1e-12 || !dem.valid(col, r)) continue;
      worst = std::max(worst, std::abs(wa * a[2] + wb * b[2] + wc * c[2] - dem.at(col, r)));
    }
  // Crossings of the edges with the grid lines x = k, y = k and the diagonals x - y = k.
  const std::array<const std::array<double, 3>*, 3> v{&a, &b, &c};
  for (int e = 0; e < 3; ++e) {
    const auto& p = *v[std::size_t(e)];
    const auto& q = *v[std::size_t((e + 1) % 3)];
    auto along = [&](double up, double uq) {
      if (up == uq) return;
      for (double k = std::floor(std::min(up, uq)) + 1; k < std::max(up, uq); ++k) {
        const double t = (k - up) / (uq - up);
        const double x = p[0] + t * (q[0] - p[0]), y = p[1] + t * (q[1] - p[1]), z = p[2] + t * (q[2] - p[2]);
        worst = std::max(worst, std::abs(z - surf.surface_height(x, y)));
      }
    };
    along(p[0], q[0]);
    along(p[1], q[1]);
    along(p[0] - p[1], q[0] - q[1]);
  }
  return worst;
}

HybridTree HybridTree::build(const HybridTerrain& h, const pm::Heightfield& dem,
                             const HybridTreeOptions& options) {
  assert(options.patch >= 1);
  const int L = h.levels();
  const LevelEncoding& top = h.level(L - 1);
  const int nx = top.cells_x, ny = top.cells_y, cs = top.cell_size;
  const std::size_t cells = std::size_t(nx) * std::size_t(ny);
  const std::int64_t cs_l = std::int64_t(cs) * kScale;

  // Hybrid surfaces per level and coarsest cell.
  std::vector<std::vector<NodeSurface>> hyb(static_cast<std::size_t>(L));
  for (auto& level_surfaces : hyb) level_surfaces.resize(cells);
  for (int l = 0; l < L; ++l) {
    const HybridMesh raw =
        Extractor::extract(h, std::vector<int>(cells, l), Scheme::Triangles, /*remove_t_junctions=*/false);
    std::vector<std::vector<std::uint32_t>> tris(cells);
    auto lp = [&](std::uint32_t v) { return LPoint{lattice(raw.points[v][0]), lattice(raw.points[v][1])}; };
    for (std::size_t t = 0; t < raw.triangles.size(); ++t) {
      const auto& tr = raw.triangles[t];
      tris[owner_cell(lp(tr[0]), lp(tr[1]), lp(tr[2]), cs_l, nx, ny)].push_back(std::uint32_t(t));
    }
    std::vector<std::uint32_t> local(raw.points.size());
    std::vector<std::size_t> stamp(raw.points.size(), cells);  // the cell local[v] belongs to
    for (std::size_t cell = 0; cell < cells; ++cell) {
      NodeSurface& s = hyb[std::size_t(l)][cell];
      for (std::uint32_t t : tris[cell]) {
        std::array<std::uint32_t, 3> out;
        for (int k = 0; k < 3; ++k) {
          const std::uint32_t v = raw.triangles[t][std::size_t(k)];
          if (stamp[v] != cell) {
            stamp[v] = cell;
            local[v] = std::uint32_t(s.points.size());
            s.points.push_back(raw.points[v]);
          }
          out[std::size_t(k)] = local[v];
        }
        s.triangles.push_back(out);
      }
    }
  }

  // Heights of grid-only nodes: the TIN vertex's where one sits on a grid node.
  std::unordered_map<std::uint64_t, double> tin_z;
  for (const auto& v : Extractor::vertices(h)) tin_z.emplace(key(v.x, v.y), v.z);
  auto grid_z = [&](int c, int r) {
    auto it = tin_z.find(key(std::int64_t(c) * kScale, std::int64_t(r) * kScale));
    return it != tin_z.end() ? it->second : dem.at(c, r);
  };

  int g0 = 1;
  while (g0 < std::max(nx, ny)) g0 *= 2;
  std::vector<TreeNode> nodes;
  std::vector<Pending> queue{{false, 0, 0, g0, 0, -1, 0}};
  std::size_t max_points = 0;
  for (std::size_t qi = 0; qi < queue.size(); ++qi) {
    const Pending p = queue[qi];
    TreeNode n;
    n.id = std::int64_t(qi);
    n.parent = p.parent;
    n.level = p.depth;
    if (p.parent >= 0) nodes[std::size_t(p.parent)].children.push_back(n.id);
    if (p.hybrid) {
      n.strategy = Strategy::Hybrid;
      n.domain = {p.i0 * cs, p.j0 * cs, (p.i0 + 1) * cs, (p.j0 + 1) * cs};
      n.surface =
          std::move(hyb[std::size_t(p.level)][std::size_t(p.j0) * std::size_t(nx) + std::size_t(p.i0)]);
      if (p.level > 0) queue.push_back({true, p.i0, p.j0, 1, p.level - 1, n.id, p.depth + 1});
    } else {
      n.strategy = Strategy::Grid;
      n.domain = {p.i0 * cs, p.j0 * cs, std::min(p.i0 + p.g, nx) * cs, std::min(p.j0 + p.g, ny) * cs};
      const int spacing = cs * p.g / std::min(p.g, options.patch);
      for (int c = n.domain.col0;; c = std::min(c + spacing, n.domain.col1)) {
        n.surface.cols.push_back(c);
        if (c == n.domain.col1) break;
      }
      for (int r = n.domain.row0;; r = std::min(r + spacing, n.domain.row1)) {
        n.surface.rows.push_back(r);
        if (r == n.domain.row1) break;
      }
      for (int r : n.surface.rows)
        for (int c : n.surface.cols) n.surface.points.push_back({double(c), double(r), grid_z(c, r)});
      triangulate_grid(n.surface);
      if (p.g == 1) {
        queue.push_back({true, p.i0, p.j0, 1, L - 1, n.id, p.depth + 1});
      } else {
        const int half = p.g / 2;
        for (int b = 0; b < 2; ++b)
          for (int a = 0; a < 2; ++a)
            if (p.i0 + a * half < nx && p.j0 + b * half < ny)
              queue.push_back({false, p.i0 + a * half, p.j0 + b * half, half, 0, n.id, p.depth + 1});
      }
    }
    n.error = surface_error(dem, n.surface);
    n.bbox = node_box(dem, n.domain, n.surface);
    max_points = std::max(max_points, n.surface.points.size());
    nodes.push_back(std::move(n));
  }
  ApproximationTree::Parameters params;
  params.max_points = max_points;
  params.max_children = 4;
  params.patch = options.patch;
  params.metric = pm::ErrorMetric::Continuous;
  params.transform = dem.transform;
  params.grid_width = dem.width();
  params.grid_height = dem.height();
  HybridTree out;
  out.tree_ = ApproximationTree(params, std::move(nodes));
  out.index(h, dem.source.empty() ? "hybrid tree" : dem.source);
  return out;
}

HybridTree HybridTree::attach(const HybridTerrain& h, ApproximationTree tree, const std::string& what) {
  HybridTree out;
  out.tree_ = std::move(tree);
  out.index(h, what);
  return out;
}

void HybridTree::index(const HybridTerrain& h, const std::string& what) {
  levels_ = h.levels();
  const LevelEncoding& top = h.level(levels_ - 1);
  cells_x_ = top.cells_x, cells_y_ = top.cells_y, cell_size_ = top.cell_size;
  line_step_ = std::int64_t(h.grid_step()) * kScale;
  const std::size_t cells = std::size_t(cells_x_) * std::size_t(cells_y_);
  auto bad = [&](const std::string& why) { return HybridError(what + ": hybrid tree: " + why); };
  if (tree_.size() == 0) throw bad("empty tree");
  if (tree_.root().domain != SampleRect{0, 0, h.domain_width(), h.domain_height()})
    throw bad("the root's domain is not the hybrid terrain's " + std::to_string(h.domain_width()) + "x" +
              std::to_string(h.domain_height()) + " samples");
  node_level_.assign(tree_.size(), -1);
  top_node_.assign(cells, -1);
  std::size_t chains = 0;
  for (const TreeNode& n : tree_.nodes()) {
    if (n.strategy == Strategy::Grid) {
      if (n.parent >= 0 && tree_.node(n.parent).strategy != Strategy::Grid)
        throw bad("a grid node below a hybrid node");
      continue;
    }
    if (n.strategy != Strategy::Hybrid)
      throw bad(std::string("a node of strategy ") + strategy_name(n.strategy));
    const TreeNode& up = tree_.node(n.parent);
    const int lv = up.strategy == Strategy::Grid ? levels_ - 1 : node_level_[std::size_t(up.id)] - 1;
    const SampleRect& d = n.domain;
    if (lv < 0 || d.col1 - d.col0 != cell_size_ || d.row1 - d.row0 != cell_size_ ||
        d.col0 % cell_size_ != 0 || d.row0 % cell_size_ != 0 ||
        (up.strategy == Strategy::Hybrid && up.domain != d))
      throw bad("node " + std::to_string(n.id) + " is not a coarsest cell at a valid level");
    if (n.leaf() != (lv == 0))
      throw bad("node " + std::to_string(n.id) + ": the level chain is not " + std::to_string(levels_) +
                " long");
    node_level_[std::size_t(n.id)] = lv;
    if (lv == levels_ - 1) {
      const std::size_t cell =
          std::size_t(d.row0 / cell_size_) * std::size_t(cells_x_) + std::size_t(d.col0 / cell_size_);
      if (cell >= cells || top_node_[cell] >= 0)
        throw bad("node " + std::to_string(n.id) + ": a second chain for one cell");
      top_node_[cell] = n.id;
      ++chains;
    }
  }
  if (chains != cells)
    throw bad(std::to_string(chains) + " hybrid cells for " + std::to_string(cells) + " coarsest cells");

  // Clusters: coarsest cells tied together by TIN triangles (closed squares meeting a triangle's
  // bounding rectangle), and the TIN triangles each cell owns (centroid).
  const std::int64_t cs_l = std::int64_t(cell_size_) * kScale;
  const auto& verts = Extractor::vertices(h);
  std::vector<std::size_t> parent(cells);
  std::iota(parent.begin(), parent.end(), std::size_t(0));
  std::function<std::size_t(std::size_t)> find = [&](std::size_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  std::vector<char> touched(cells, 0);
  tin_owned_.assign(cells, 0);
  auto floor_div = [](std::int64_t a, std::int64_t b) { return a >= 0 ? a / b : -((-a + b - 1) / b); };
  for (const auto& t : Extractor::tin(h)) {
    const LPoint a{verts[t[0]].x, verts[t[0]].y}, b{verts[t[1]].x, verts[t[1]].y},
        c{verts[t[2]].x, verts[t[2]].y};
    ++tin_owned_[owner_cell(a, b, c, cs_l, cells_x_, cells_y_)];
    const std::int64_t x0 = std::min({a.x, b.x, c.x}), x1 = std::max({a.x, b.x, c.x});
    const std::int64_t y0 = std::min({a.y, b.y, c.y}), y1 = std::max({a.y, b.y, c.y});
    const int i0 = int(std::max<std::int64_t>(0, -floor_div(-x0, cs_l) - 1)),
              i1 = int(std::min<std::int64_t>(cells_x_ - 1, x1 / cs_l));
    const int j0 = int(std::max<std::int64_t>(0, -floor_div(-y0, cs_l) - 1)),
              j1 = int(std::min<std::int64_t>(cells_y_ - 1, y1 / cs_l));
    const std::size_t first = std::size_t(j0) * std::size_t(cells_x_) + std::size_t(i0);
    for (int j = j0; j <= j1; ++j)
      for (int i = i0; i <= i1; ++i) {
        const std::size_t cell = std::size_t(j) * std::size_t(cells_x_) + std::size_t(i);
        touched[cell] = 1;
        parent[find(cell)] = find(first);
      }
  }
  cluster_.assign(cells, -1);
  for (std::size_t cell = 0; cell < cells; ++cell)
    if (touched[cell]) cluster_[cell] = int(find(cell));
}

HybridSelection HybridTree::assemble(std::span<const std::int64_t> selected) const {
  HybridSelection out;
  const std::size_t cells = std::size_t(cells_x_) * std::size_t(cells_y_);
  auto cell_of = [&](const TreeNode& n) {
    return std::size_t(n.domain.row0 / cell_size_) * std::size_t(cells_x_) +
           std::size_t(n.domain.col0 / cell_size_);
  };
  std::vector<char> active(cells, 0);  // indexed by cluster id (a cell index)
  for (std::int64_t id : selected) {
    const TreeNode& n = tree_.node(id);
    if (n.strategy == Strategy::Hybrid && cluster_[cell_of(n)] >= 0)
      active[std::size_t(cluster_[cell_of(n)])] = 1;
  }
  auto covers_active = [&](const TreeNode& n) {
    for (int j = n.domain.row0 / cell_size_; j < n.domain.row1 / cell_size_; ++j)
      for (int i = n.domain.col0 / cell_size_; i < n.domain.col1 / cell_size_; ++i) {
        const int c = cluster_[std::size_t(j) * std::size_t(cells_x_) + std::size_t(i)];
        if (c >= 0 && active[std::size_t(c)]) return true;
      }
    return false;
  };
  std::function<void(std::int64_t)> visit = [&](std::int64_t id) {
    const TreeNode& n = tree_.node(id);
    if (n.strategy == Strategy::Grid && covers_active(n)) {
      ++out.forced;
      for (std::int64_t c : n.children) visit(c);
      return;
    }
    out.nodes.push_back(id);
  };
  for (std::int64_t id : selected) visit(id);
  // Cells of drawn clusters that the selection left out (culled): their TIN triangles may reach
  // into drawn cells, so they are drawn too, at the coarsest hybrid level.
  std::vector<char> covered(cells, 0);
  for (std::int64_t id : out.nodes) {
    const TreeNode& n = tree_.node(id);
    for (int j = n.domain.row0 / cell_size_; j < n.domain.row1 / cell_size_; ++j)
      for (int i = n.domain.col0 / cell_size_; i < n.domain.col1 / cell_size_; ++i)
        covered[std::size_t(j) * std::size_t(cells_x_) + std::size_t(i)] = 1;
  }
  for (std::size_t cell = 0; cell < cells; ++cell)
    if (!covered[cell] && cluster_[cell] >= 0 && active[std::size_t(cluster_[cell])]) {
      out.nodes.push_back(top_node_[cell]);
      ++out.added;
    }

  out.cell_level.assign(cells, -2);
  std::vector<LPoint> lp;
  std::unordered_map<std::uint64_t, std::uint32_t> at;
  HybridMesh& m = out.mesh;
  for (std::int64_t id : out.nodes) {
    const TreeNode& n = tree_.node(id);
    const int lv = node_level_[std::size_t(id)];
    if (lv >= 0) {
      ++out.hybrid_nodes;
      out.cell_level[cell_of(n)] = lv;
      out.tin_triangles += tin_owned_[cell_of(n)];
    } else {
      ++out.grid_nodes;
      m.grid_triangles += n.surface.triangles.size();
      for (int j = n.domain.row0 / cell_size_; j < n.domain.row1 / cell_size_; ++j)
        for (int i = n.domain.col0 / cell_size_; i < n.domain.col1 / cell_size_; ++i)
          out.cell_level[std::size_t(j) * std::size_t(cells_x_) + std::size_t(i)] = -1;
    }
    out.error_m = std::max(out.error_m, n.error);
    std::vector<std::uint32_t> map(n.surface.points.size());
    for (std::size_t v = 0; v < map.size(); ++v) {
      const auto& p = n.surface.points[v];
      const LPoint q{lattice(p[0]), lattice(p[1])};
      auto [it, fresh] = at.emplace(key(q.x, q.y), std::uint32_t(lp.size()));
      if (fresh) {
        lp.push_back(q);
        m.points.push_back({double(q.x) / kScale, double(q.y) / kScale, p[2]});
      } else if (m.points[it->second][2] != p[2]) {
        ++out.height_conflicts;
      }
      map[v] = it->second;
    }
    for (const auto& t : n.surface.triangles) m.triangles.push_back({map[t[0]], map[t[1]], map[t[2]]});
  }
  m.tin_triangles = out.tin_triangles;
  m.split_edges = split_t_junctions(lp, m.triangles, line_step_);
  return out;
}

HybridSelection HybridTree::select(const pm::View& view, const SelectionOptions& options) const {
  SelectionResult sel = select_nodes(tree_, view, options);
  HybridSelection out = assemble(sel.selected);
  out.selection = std::move(sel);
  for (std::int64_t id : out.nodes)
    out.bound_px = std::max(out.bound_px, view.vertical_error_px(tree_.node(id).bbox, tree_.node(id).error));
  return out;
}

}  // namespace terralod::blocks::hybrid
