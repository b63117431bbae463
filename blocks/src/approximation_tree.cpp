// Approximation tree: node storage, the "tree" blob format, and the per-frame selection
// (seeds/approximation-tree.txt, sections 3.1 and 4). Memory: the nodes; the selection keeps a
// stack of at most depth * d node ids.
#include "terralod/blocks/approximation_tree.hpp"

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <cstring>

#include "terralod/pm/byte_io.hpp"
#include "terralod/pm/memory_bytes.hpp"

namespace terralod::blocks {

const char* strategy_name(Strategy s) {
  switch (s) {
    case Strategy::Grid:
      return "grid";
    case Strategy::Tin:
      return "tin";
    case Strategy::NonRegularGrid:
      return "nonregular";
    case Strategy::PmBlock:
      return "pm_block";
    case Strategy::Hybrid:
      return "hybrid";
  }
  return "unknown";
}

ApproximationTree::ApproximationTree(Parameters parameters, std::vector<TreeNode> nodes)
    : params_(std::move(parameters)), nodes_(std::move(nodes)) {
#ifndef NDEBUG
  for (std::size_t i = 0; i < nodes_.size(); ++i) {
    assert(nodes_[i].id == std::int64_t(i));
    assert(i == 0 ? nodes_[i].parent == -1 : (nodes_[i].parent >= 0 && nodes_[i].parent < std::int64_t(i)));
    for (std::int64_t c : nodes_[i].children) assert(c > std::int64_t(i) && c < std::int64_t(nodes_.size()));
  }
#endif
}

std::array<std::size_t, kStrategyCount> ApproximationTree::count_by_strategy() const {
  std::array<std::size_t, kStrategyCount> c{};
  for (const TreeNode& n : nodes_) ++c[std::size_t(n.strategy)];
  return c;
}

int ApproximationTree::depth() const {
  int d = 0;
  for (const TreeNode& n : nodes_) d = std::max(d, n.level + 1);
  return d;
}

std::size_t ApproximationTree::memory_bytes() const {
  std::size_t n = pm::capacity_bytes(nodes_);
  for (const TreeNode& t : nodes_)
    n += pm::capacity_bytes(t.children) + pm::capacity_bytes(t.surface.points) +
         pm::capacity_bytes(t.surface.triangles) + pm::capacity_bytes(t.surface.cols) +
         pm::capacity_bytes(t.surface.rows);
  return n;
}

// ---------------------------------------------------------------------------------------------
// The "tree" blob, format version 1. All integers little-endian; "varint" = unsigned LEB128
// (7 bits per byte, low first, high bit = more; at most 10 bytes); "f64" = IEEE-754 binary64
// little-endian, bit-exact.
//
//   offset  size   field
//   0       8      magic "TLODTREE"
//   8       4      u32 format version (1)
//   12      ...    varint max_points s, varint max_children d, varint patch P, u8 metric
//                  (0 = samples, 1 = continuous), 6 x f64 GridTransform x0 xc xr y0 yc yr,
//                  varint grid_width, varint grid_height, varint node count n
//   then n node records, in id order (id = position; parents precede children):
//     varint parent + 1         (0 for the root)
//     u8     strategy           (Strategy's value)
//     varint level
//     varint col0, row0, col1 - col0, row1 - row0   (domain, whole-grid samples)
//     f64    error              (metres)
//     6 x f64 bbox lo.x lo.y lo.z hi.x hi.y hi.z   (world metres)
//     f64    texel_m
//     varint child count k, then k x varint child id
//     PmBlock:      varint block col, varint block row  (the database block; non-negative)
//     Grid, NonRegularGrid:
//                   varint nc, varint nr, nc x varint (cols[i] - col0),
//                   nr x varint (rows[j] - row0), nc * nr x f64 heights (row-major);
//                   triangles are implied: two per cell, split along the cell's
//                   (cols[i],rows[j])-(cols[i+1],rows[j+1]) diagonal
//     Tin:          varint point count m, m x (varint col - col0, varint row - row0, f64 z),
//                   varint triangle count t, t x 3 varint point indices
//     Hybrid:       varint point count m, m x (f64 col, f64 row, f64 z) (points off the samples:
//                   TIN boundary intersections; TIN triangles may reach past the domain),
//                   varint triangle count t, t x 3 varint point indices
//   trailer: u32 CRC-32 (zlib) of every byte before it.
// ---------------------------------------------------------------------------------------------
namespace {

constexpr std::uint8_t kMagic[8] = {'T', 'L', 'O', 'D', 'T', 'R', 'E', 'E'};

[[noreturn]] void fail_at(const std::string& name, const std::string& what, std::size_t pos) {
  throw TreeFormatError(name + ": " + what + " (at byte " + std::to_string(pos) + ")");
}

/// The words of a failed read in the blob's errors.
const char* read_failure(pm::ByteReadFailure::Kind kind) {
  switch (kind) {
    case pm::ByteReadFailure::Kind::Truncated:
    case pm::ByteReadFailure::Kind::VarintTruncated:
      return "truncated";
    case pm::ByteReadFailure::Kind::VarintTooLong:
      return "varint overflow";
    case pm::ByteReadFailure::Kind::VarintNotShortest:
      return "non-canonical varint";
  }
  return "unreadable";
}

/// The blob's reads: varints only in their shortest form (so that decoding is one-to-one), and
/// every error names the blob and the byte it was found at.
struct Reader : pm::ByteReader {
  const std::string& name;
  Reader(std::span<const std::uint8_t> bytes, const std::string& blob_name)
      : pm::ByteReader(
            bytes,
            [&blob_name](const pm::ByteReadFailure& f) {
              fail_at(blob_name, read_failure(f.kind), f.position);
            },
            pm::VarintForm::Shortest),
        name(blob_name) {}
  [[noreturn]] void fail(const std::string& what) const { fail_at(name, what, position()); }
  /// A varint that must be <= limit.
  std::uint64_t var(std::uint64_t limit, const char* what) {
    const std::uint64_t v = varint();
    if (v > limit) fail(std::string("bad ") + what + " " + std::to_string(v));
    return v;
  }
};

void write_node(pm::ByteWriter& w, const TreeNode& n) {
  w.varint(std::uint64_t(n.parent + 1));
  w.u8(std::uint8_t(n.strategy));
  w.varint(std::uint64_t(n.level));
  w.varint(std::uint64_t(n.domain.col0));
  w.varint(std::uint64_t(n.domain.row0));
  w.varint(std::uint64_t(n.domain.col1 - n.domain.col0));
  w.varint(std::uint64_t(n.domain.row1 - n.domain.row0));
  w.f64(n.error);
  for (double v : {n.bbox.lo.x, n.bbox.lo.y, n.bbox.lo.z, n.bbox.hi.x, n.bbox.hi.y, n.bbox.hi.z}) w.f64(v);
  w.f64(n.texel_m);
  w.varint(n.children.size());
  for (std::int64_t c : n.children) w.varint(std::uint64_t(c));
  const NodeSurface& s = n.surface;
  switch (n.strategy) {
    case Strategy::PmBlock:
      assert(n.block && n.block->col >= 0 && n.block->row >= 0);
      w.varint(std::uint64_t(n.block->col));
      w.varint(std::uint64_t(n.block->row));
      break;
    case Strategy::Grid:
    case Strategy::NonRegularGrid:
      assert(s.points.size() == s.cols.size() * s.rows.size());
      w.varint(s.cols.size());
      w.varint(s.rows.size());
      for (int c : s.cols) w.varint(std::uint64_t(c - n.domain.col0));
      for (int r : s.rows) w.varint(std::uint64_t(r - n.domain.row0));
      for (const auto& p : s.points) w.f64(p[2]);
      break;
    case Strategy::Tin:
    case Strategy::Hybrid:
      w.varint(s.points.size());
      for (const auto& p : s.points) {
        if (n.strategy == Strategy::Hybrid) {
          w.f64(p[0]);
          w.f64(p[1]);
        } else {
          w.varint(std::uint64_t(int(p[0]) - n.domain.col0));
          w.varint(std::uint64_t(int(p[1]) - n.domain.row0));
        }
        w.f64(p[2]);
      }
      w.varint(s.triangles.size());
      for (const auto& t : s.triangles)
        for (std::uint32_t v : t) w.varint(v);
      break;
  }
}

}  // namespace

void triangulate_grid(NodeSurface& s) {
  const std::uint32_t nc = std::uint32_t(s.cols.size()), nr = std::uint32_t(s.rows.size());
  s.triangles.clear();
  for (std::uint32_t j = 0; j + 1 < nr; ++j)
    for (std::uint32_t i = 0; i + 1 < nc; ++i) {
      const std::uint32_t a = j * nc + i, b = a + 1, c = a + nc + 1, d = a + nc;
      s.triangles.push_back({a, b, c});
      s.triangles.push_back({a, c, d});
    }
}

std::size_t encoded_node_bytes(const TreeNode& node) {
  pm::ByteWriter w;
  write_node(w, node);
  return w.bytes.size();
}

std::vector<std::uint8_t> encode_tree(const ApproximationTree& tree) {
  pm::ByteWriter w;
  w.bytes.reserve(4096);  // (also keeps GCC 12's -Wstringop-overflow false positive away in sanitizer builds)
  w.raw(kMagic);
  w.u32(kTreeFormatVersion);
  const auto& p = tree.parameters();
  w.varint(p.max_points);
  w.varint(std::uint64_t(p.max_children));
  w.varint(std::uint64_t(p.patch));
  w.u8(std::uint8_t(p.metric));
  for (double v :
       {p.transform.x0, p.transform.xc, p.transform.xr, p.transform.y0, p.transform.yc, p.transform.yr})
    w.f64(v);
  w.varint(std::uint64_t(p.grid_width));
  w.varint(std::uint64_t(p.grid_height));
  w.varint(tree.size());
  for (const TreeNode& n : tree.nodes()) write_node(w, n);
  w.u32(pm::crc32_of(w.bytes));
  return std::move(w.bytes);
}

ApproximationTree decode_tree(std::span<const std::uint8_t> bytes, const std::string& name) {
  if (bytes.size() < 16 || std::memcmp(bytes.data(), kMagic, 8) != 0)
    fail_at(name, "not an approximation tree (bad magic)", 0);
  {
    const std::uint32_t stored = pm::load_u32(bytes.data() + bytes.size() - 4);
    if (pm::crc32_of(bytes.first(bytes.size() - 4)) != stored) fail_at(name, "checksum mismatch", 0);
  }
  Reader r(bytes.first(bytes.size() - 4), name);
  r.raw(8);  // the magic
  const std::uint32_t version = r.u32();
  if (version != kTreeFormatVersion)
    r.fail("unsupported tree format version " + std::to_string(version) + " (this build reads " +
           std::to_string(kTreeFormatVersion) + ")");
  ApproximationTree::Parameters p;
  p.max_points = std::size_t(r.var(std::uint64_t(1) << 32, "max_points"));
  p.max_children = int(r.var(1 << 16, "max_children"));
  p.patch = int(r.var(1 << 16, "patch"));
  const std::uint8_t metric = r.u8();
  if (metric > 1) r.fail("bad metric " + std::to_string(metric));
  p.metric = pm::ErrorMetric(metric);
  p.transform.x0 = r.f64();
  p.transform.xc = r.f64();
  p.transform.xr = r.f64();
  p.transform.y0 = r.f64();
  p.transform.yc = r.f64();
  p.transform.yr = r.f64();
  p.grid_width = int(r.var(1 << 30, "grid width"));
  p.grid_height = int(r.var(1 << 30, "grid height"));
  // A node record takes at least 1+1+1+4+8+48+8+1 = 72 bytes.
  const std::uint64_t n = r.var(r.left() / 72, "node count");
  std::vector<TreeNode> nodes(static_cast<std::size_t>(n));
  for (std::uint64_t id = 0; id < n; ++id) {
    TreeNode& t = nodes[id];
    t.id = std::int64_t(id);
    t.parent = std::int64_t(r.var(id, "parent")) - 1;
    if ((id == 0) != (t.parent == -1)) r.fail("node " + std::to_string(id) + ": bad parent");
    const std::uint8_t strategy = r.u8();
    if (strategy >= kStrategyCount) r.fail("node " + std::to_string(id) + ": bad strategy");
    t.strategy = Strategy(strategy);
    t.level = int(r.var(1 << 20, "level"));
    t.domain.col0 = int(r.var(std::uint64_t(std::max(0, p.grid_width - 1)), "column"));
    t.domain.row0 = int(r.var(std::uint64_t(std::max(0, p.grid_height - 1)), "row"));
    t.domain.col1 =
        t.domain.col0 + int(r.var(std::uint64_t(std::max(0, p.grid_width - 1 - t.domain.col0)), "width"));
    t.domain.row1 =
        t.domain.row0 + int(r.var(std::uint64_t(std::max(0, p.grid_height - 1 - t.domain.row0)), "height"));
    t.error = r.f64();
    t.bbox.lo = {r.f64(), r.f64(), r.f64()};
    t.bbox.hi = {r.f64(), r.f64(), r.f64()};
    t.texel_m = r.f64();
    const std::uint64_t k = r.var(r.left(), "child count");
    for (std::uint64_t i = 0; i < k; ++i) {
      const std::uint64_t c = r.var(n - 1, "child id");
      if (c <= id)
        r.fail("node " + std::to_string(id) + ": child " + std::to_string(c) + " does not follow it");
      t.children.push_back(std::int64_t(c));
    }
    NodeSurface& s = t.surface;
    switch (t.strategy) {
      case Strategy::PmBlock: {
        const int bc = int(r.var(1 << 30, "block column")), br = int(r.var(1 << 30, "block row"));
        t.block = BlockKey{bc, br};
        break;
      }
      case Strategy::Grid:
      case Strategy::NonRegularGrid: {
        const std::uint64_t nc = r.var(std::uint64_t(t.domain.width()), "column count");
        const std::uint64_t nr = r.var(std::uint64_t(t.domain.height()), "row count");
        if (nc * nr > r.left() / 8)
          r.fail("node " + std::to_string(id) + ": grid larger than the bytes left");
        for (std::uint64_t i = 0; i < nc; ++i)
          s.cols.push_back(t.domain.col0 + int(r.var(std::uint64_t(t.domain.width() - 1), "column")));
        for (std::uint64_t j = 0; j < nr; ++j)
          s.rows.push_back(t.domain.row0 + int(r.var(std::uint64_t(t.domain.height() - 1), "row")));
        s.points.reserve(std::size_t(nc * nr));
        for (std::uint64_t j = 0; j < nr; ++j)
          for (std::uint64_t i = 0; i < nc; ++i)
            s.points.push_back({double(s.cols[i]), double(s.rows[j]), r.f64()});
        triangulate_grid(s);
        break;
      }
      case Strategy::Tin:
      case Strategy::Hybrid: {
        const std::uint64_t m = r.var(r.left() / 10, "point count");
        s.points.reserve(std::size_t(m));
        for (std::uint64_t i = 0; i < m; ++i) {
          if (t.strategy == Strategy::Hybrid) {
            const double c = r.f64(), rr = r.f64();
            if (!std::isfinite(c) || !std::isfinite(rr))
              r.fail("node " + std::to_string(id) + ": point not finite");
            s.points.push_back({c, rr, r.f64()});
            continue;
          }
          const int c = t.domain.col0 + int(r.var(std::uint64_t(t.domain.width() - 1), "point column"));
          const int rr = t.domain.row0 + int(r.var(std::uint64_t(t.domain.height() - 1), "point row"));
          s.points.push_back({double(c), double(rr), r.f64()});
        }
        const std::uint64_t nt = r.var(r.left() / 3, "triangle count");
        if (nt > 0 && m < 3)  // (found by fuzz_tree_decoder: indices of an empty point list)
          r.fail("node " + std::to_string(id) + ": " + std::to_string(nt) + " triangles over " +
                 std::to_string(m) + " points");
        s.triangles.reserve(std::size_t(nt));
        for (std::uint64_t i = 0; i < nt; ++i) {
          std::array<std::uint32_t, 3> tri{};
          for (auto& v : tri) v = std::uint32_t(r.var(m == 0 ? 0 : m - 1, "point index"));
          s.triangles.push_back(tri);
        }
        break;
      }
    }
  }
  if (r.left() != 0) r.fail(std::to_string(r.left()) + " unexpected bytes after the last node");
  std::vector<char> listed(nodes.size(), 0);
  for (const TreeNode& t : nodes)
    for (std::int64_t c : t.children) {
      if (nodes[std::size_t(c)].parent != t.id || listed[std::size_t(c)])
        r.fail("node " + std::to_string(c) + ": listed by a node that is not its parent, or twice");
      listed[std::size_t(c)] = 1;
    }
  for (std::size_t i = 1; i < nodes.size(); ++i)
    if (!listed[i]) r.fail("node " + std::to_string(i) + ": its parent does not list it");
  return ApproximationTree(std::move(p), std::move(nodes));
}

// ---------------------------------------------------------------------------------------------
// Selection

double paper_alpha_px(const pm::View& view, const pm::Box& b, double error_m) {
  const pm::Vec3& e = view.eye();
  const pm::Vec3 p{std::clamp(e.x, b.lo.x, b.hi.x), std::clamp(e.y, b.lo.y, b.hi.y),
                   std::clamp(e.z, b.lo.z, b.hi.z)};
  if (p.x == e.x && p.y == e.y && p.z == e.z) return std::numeric_limits<double>::infinity();
  if (error_m <= 0.0) return 0.0;
  pm::Vec3 a{p.x, p.y, p.z - 0.5 * error_m}, c{p.x, p.y, p.z + 0.5 * error_m};
  // Clip the segment to depth >= near (depth is affine along it).
  const double near = view.camera().near_m;
  const double da = view.depth(a), dc = view.depth(c);
  if (da < near && dc < near) return std::numeric_limits<double>::infinity();
  if (da < near || dc < near) {
    const double t = (near - da) / (dc - da);  // where depth == near
    const pm::Vec3 m{a.x + t * (c.x - a.x), a.y + t * (c.y - a.y), a.z + t * (c.z - a.z)};
    (da < near ? a : c) = m;
  }
  double ax, ay, cx, cy;
  view.project(a, ax, ay);
  view.project(c, cx, cy);
  return std::hypot(cx - ax, cy - ay);
}

// Why the selection tests View::vertical_error_px over the whole box, not the paper's alpha.
// The paper's alpha measures one segment, at the point p of B_N nearest the eye. The error of
// N can sit anywhere in D_N, and a vertical segment elsewhere in the box can project longer:
//   - the projected length of a vertical segment is K * (speed factor) * length / depth, and
//     the nearest point (Euclidean) is not the point of smallest depth: for an oblique box the
//     corner nearest the image plane can be farther from the eye than p but shallower;
//   - the speed factor depends on where the segment lands in the image. Looking straight
//     down at a box right below the eye, p is on the optical axis and its vertical segment
//     projects to a single point (alpha = 0 for any error), while the same segment at a corner
//     of the box, off the axis, projects to a radial streak of positive length (the test
//     AlphaIsNotAnUpperBound draws this case).
// vertical_error_px(box, e) = e K vf / max(zmin(box), near) bounds the image of every vertical
// segment of length <= e inside the box (pm/src/view.cpp derives it). Every error segment of N
// — from the node's surface to the terrain at a point of D_N — is vertical, no longer than
// epsilon(N), and lies in B_N (both surfaces are inside the box), so a node selected with
// bound <= threshold is drawn within the threshold on screen. alpha is reported beside it.
SelectionResult select_nodes(const ApproximationTree& tree, const pm::View& view,
                             const SelectionOptions& opt) {
  assert(opt.alpha_px > 0.0);
  const auto t0 = std::chrono::steady_clock::now();
  SelectionResult res;
  if (tree.size() == 0) return res;
  std::vector<std::int64_t> stack{0};
  while (!stack.empty()) {
    const TreeNode& n = tree.node(stack.back());
    stack.pop_back();
    ++res.visited;
    if (opt.cull && view.outside(n.bbox)) {
      ++res.culled;
      continue;
    }
    NodeVisual v;
    v.bound_px = view.vertical_error_px(n.bbox, n.error);
    bool ok = v.bound_px <= opt.alpha_px;
    if (n.texel_m > 0.0 && std::isfinite(opt.gamma_px)) {
      // gamma: area in pixels of a texel (a w x w square) at the box's smallest depth, the
      // largest magnification of a horizontal square inside the box for a level camera.
      const double side = n.texel_m * view.focal_px() * view.vertical_factor() /
                          std::max(view.min_depth(n.bbox), view.camera().near_m);
      v.gamma_px = side * side;
      ok = ok && v.gamma_px <= opt.gamma_px;
    }
    if (ok || n.leaf()) {
      v.alpha_px = paper_alpha_px(view, n.bbox, n.error);
      if (n.strategy == Strategy::PmBlock) {
        v.tolerance_px = opt.alpha_px;
        ++res.pm_blocks;
        res.bound_px = std::max(res.bound_px, std::min(v.bound_px, v.tolerance_px));
      } else {
        res.points += n.surface.points.size();
        res.triangles += n.surface.triangles.size();
        res.bound_px = std::max(res.bound_px, v.bound_px);
      }
      res.alpha_max_px = std::max(res.alpha_max_px, v.alpha_px);
      res.selected.push_back(n.id);
      res.visual.push_back(v);
      continue;
    }
    for (auto it = n.children.rbegin(); it != n.children.rend(); ++it) stack.push_back(*it);
  }
  res.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

}  // namespace terralod::blocks
