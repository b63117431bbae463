// Vertex hierarchy (Hoppe 1997; view-dependent PM paper, section 3, Figs. 2 and 4): forest of
// vsplits, saturated errors, and bounding spheres computed bottom-up.
//
// Build in three linear passes: (1) one pass over the full-resolution faces marks the mesh
// vertices and the squared length of each vertex's longest incident edge (the leaf radius);
// (2) replaying the vsplits in order fills two children per split (sample, parent, depth),
// tracking which node currently represents each sample, so that at the end it knows the
// leaves; (3) undoing the vsplits from the last one saturates errors and grows the spheres
// (Fig. 4) and links each node to the vsplit that splits it. The collapse order is spatially
// random, so the passes touch only per-sample arrays at random and write nodes_ in order
// (random access into the nodes would cost two more cache misses per vsplit).
// Memory: 32 bytes per node + 8 per vsplit + 4 per sample, plus up to 32 bytes per sample of
// scratch during the build.
#include "terralod/pm/vertex_hierarchy.hpp"

#include <algorithm>
#include <array>
#include <cmath>

namespace terralod::pm {

namespace {

struct WorldPos {
  double x, y, z;
};

}  // namespace

VertexHierarchy::VertexHierarchy(const ProgressiveMesh& pm) {
  const Heightfield& hf = pm.heightfield();
  const std::uint32_t W = std::uint32_t(hf.width());
  const std::size_t n = hf.size();
  const GridTransform& t = hf.transform;
  // (1) Mesh vertices and leaf radii (squared) from the full-resolution faces, cell by cell:
  // the even face (v00, v10, v11) owns edges top, right and diagonal; the odd face
  // (v00, v11, v01) the diagonal, bottom and left. Positions come from (i, j) directly.
  std::vector<double> r2(n, -1.0);  // -1: not a mesh vertex
  const bool sparse = hf.has_holes() || !pm.dropped_faces().empty();
  std::array<std::uint32_t, 3> tri;
  auto edge = [&r2](std::uint32_t a, const WorldPos& pa, std::uint32_t b, const WorldPos& pb) {
    const double d2 =
        (pa.x - pb.x) * (pa.x - pb.x) + (pa.y - pb.y) * (pa.y - pb.y) + (pa.z - pb.z) * (pa.z - pb.z);
    r2[a] = std::max(r2[a], d2);
    r2[b] = std::max(r2[b], d2);
  };
  const std::uint32_t H = std::uint32_t(hf.height());
  for (std::uint32_t j = 0; j + 1 < H; ++j)
    for (std::uint32_t i = 0; i + 1 < W; ++i) {
      const std::uint32_t cell = j * (W - 1) + i;
      const bool even = !sparse || pm.full_face(2 * cell, tri),
                 odd = !sparse || pm.full_face(2 * cell + 1, tri);
      if (!even && !odd) continue;
      const std::uint32_t v00 = j * W + i, v10 = v00 + 1, v01 = v00 + W, v11 = v01 + 1;
      const double c0 = i, c1 = i + 1, r0 = j, r1 = j + 1;  // same arithmetic as to_world()
      const WorldPos p00{t.x0 + c0 * t.xc + r0 * t.xr, t.y0 + c0 * t.yc + r0 * t.yr, hf[v00]},
          p10{t.x0 + c1 * t.xc + r0 * t.xr, t.y0 + c1 * t.yc + r0 * t.yr, hf[v10]},
          p01{t.x0 + c0 * t.xc + r1 * t.xr, t.y0 + c0 * t.yc + r1 * t.yr, hf[v01]},
          p11{t.x0 + c1 * t.xc + r1 * t.xr, t.y0 + c1 * t.yc + r1 * t.yr, hf[v11]};
      edge(v00, p00, v11, p11);
      if (even) edge(v00, p00, v10, p10), edge(v10, p10, v11, p11);
      if (odd) edge(v11, p11, v01, p01), edge(v01, p01, v00, p00);
    }

  // Roots: mesh vertices that no collapse removes, in sample order.
  const std::vector<Collapse>& cs = pm.collapses();
  const std::size_t C = cs.size();
  struct Current {
    std::uint32_t node, depth;
  };
  std::vector<Current> cur(n, Current{HierarchyNode::kNone, 0});
  for (const Collapse& c : cs) cur[c.u].node = 0;  // marks removed samples
  nodes_.clear();
  nodes_.reserve(pm.base_vertex_count() + 2 * C);
  for (std::uint32_t s = 0; s < n; ++s) {
    const bool root = r2[s] >= 0.0 && cur[s].node == HierarchyNode::kNone;
    cur[s].node = HierarchyNode::kNone;
    if (root) {
      cur[s].node = std::uint32_t(nodes_.size());
      nodes_.push_back(HierarchyNode{s, HierarchyNode::kNone, HierarchyNode::kNone, 0, 0.0, 0.0});
    }
  }
  root_count_ = nodes_.size();

  // (2) Forward: vsplit k undoes collapse C-1-k; the node representing w gets children (w, u).
  // Only the per-sample array is accessed at random; nodes_ is appended in order.
  split_errors_.resize(C);
  for (std::size_t k = 0; k < C; ++k) {
    const Collapse& c = cs[C - 1 - k];
    split_errors_[k] = c.error;
    const Current p = cur[c.w];
    const auto first = std::uint32_t(nodes_.size());
    nodes_.push_back(HierarchyNode{c.w, p.node, HierarchyNode::kNone, p.depth + 1, 0.0, 0.0});
    nodes_.push_back(HierarchyNode{c.u, p.node, HierarchyNode::kNone, p.depth + 1, 0.0, 0.0});
    cur[c.w] = Current{first, p.depth + 1};
    cur[c.u] = Current{first + 1, p.depth + 1};
  }
  leaf_of_.resize(n);
  for (std::uint32_t s = 0; s < n; ++s) leaf_of_[s] = cur[s].node;
  cur = {};

  // (3) Backward: undoing vsplits from the last, a per-sample array holds the saturated error
  // and sphere radius of the node that currently represents each sample (the leaves at the
  // start) and the next vsplit that splits it. A pair of children is final when its vsplit is
  // undone, and the merged values become the parent's (Fig. 4).
  struct Up {  // 32 bytes, two per cache line; z saves a random read of the heights
    double error, radius, z;
    std::uint32_t next;
  };
  std::vector<Up> up(n);
  for (std::uint32_t s = 0; s < n; ++s)
    up[s] = Up{0.0, r2[s] >= 0.0 ? std::sqrt(r2[s]) : 0.0, hf[s], HierarchyNode::kNone};
  r2 = {};
  auto xy = [&](std::uint32_t s) {
    const double col = double(s % W), row = double(s / W);
    return std::pair{t.x0 + col * t.xc + row * t.xr, t.y0 + col * t.yc + row * t.yr};
  };
  auto finish = [&](HierarchyNode& node, const Up& v) {
    node.error = v.error;
    node.radius = v.radius;
    if (v.next != HierarchyNode::kNone)
      node.first_child = std::uint32_t(root_count_ + 2 * std::size_t(v.next));
  };
  for (std::size_t k = C; k-- > 0;) {
    const Collapse& c = cs[C - 1 - k];
    Up& w = up[c.w];
    const Up& u = up[c.u];
    finish(nodes_[root_count_ + 2 * k], w);
    finish(nodes_[root_count_ + 2 * k + 1], u);
    w.error = std::max({c.error, w.error, u.error});
    const auto [xw, yw] = xy(c.w);
    const auto [xu, yu] = xy(c.u);
    const double d = std::sqrt((xw - xu) * (xw - xu) + (yw - yu) * (yw - yu) + (w.z - u.z) * (w.z - u.z));
    w.radius = std::max(w.radius, d + u.radius);
    w.next = std::uint32_t(k);
  }
  for (std::uint32_t r = 0; r < root_count_; ++r) finish(nodes_[r], up[nodes_[r].sample]);
}

std::uint32_t VertexHierarchy::root_of(std::uint32_t node) const {
  while (nodes_[node].parent != HierarchyNode::kNone) node = nodes_[node].parent;
  return node;
}

}  // namespace terralod::pm
