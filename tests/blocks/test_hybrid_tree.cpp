// Tests of the hybrid node strategy (hybrid_tree.hpp): exact node errors against an independent
// clipping brute force, crack-free unions of random selections, TIN near / grid far, blob
// round trip, and the N44W072 valley.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <random>
#include <set>

#include "plane_cover_check.hpp"
#include "printed_seed.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/greedy_tin.hpp"
#include "terralod/blocks/hybrid/hybrid_tree.hpp"
#include "tin_fixture.hpp"

namespace hy = terralod::blocks::hybrid;
namespace tb = terralod::blocks;
namespace pm = terralod::pm;
namespace tt = terralod::test;

namespace {

using P3 = std::array<double, 3>;

// 97 x 97 samples, 10 m spacing, north-up (row 0 at y = 960): a bumpy plane.
pm::Heightfield make_grid() {
  pm::Heightfield hf = tt::bumpy_grid(97, 97);
  hf.transform = pm::GridTransform::north_up(0.0, 960.0, 10.0, 10.0);
  return hf;
}

// Two TINs (grid step 4, 3 levels: coarsest cells of 16 samples, 6 x 6 of them):
//   A: a 20 x 14 block of 2.5-sample squares at (21.5, 19.25): cells (1..4, 1..3), boundary
//      off the grid lines;
//   B: an octagon fan around (81, 81), radius 9: the four cells around (80, 80).
hy::TinMesh make_tin() {
  std::vector<std::array<double, 2>> octagon;
  for (int k = 0; k < 8; ++k) {
    const double t = k * M_PI / 4 + 0.1;
    octagon.push_back({81 + 9 * std::cos(t), 81 + 9 * std::sin(t)});
  }
  hy::TinMesh m = hy::merge_tins({tt::grid_tin(21.5, 19.25, 20, 14, 2.5), tt::fan_tin(octagon, {81, 81})});
  m.source = "test TINs";
  return m;
}

struct Fixture {
  pm::Heightfield hf = make_grid();
  hy::TinMesh tin = make_tin();
  hy::HybridTerrain h = hy::HybridTerrain::build(hf, tin, {.grid_step = 4, .levels = 3});
  hy::HybridTree tree = hy::HybridTree::build(h, hf);
};
const Fixture& fixture() {
  static const Fixture f;
  return f;
}

double orient(const P3& a, const P3& b, const P3& c) {
  return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

/// Independent exact error of one triangle: the triangle is clipped against both triangles of
/// every full-resolution cell it may meet (Sutherland-Hodgman); the two planes differ linearly
/// on each piece, so the maximum is at a piece vertex.
double brute_triangle_error(const pm::Heightfield& hf, P3 a, P3 b, P3 c) {
  if (orient(a, b, c) < 0) std::swap(b, c);
  auto plane_at = [](const P3& p, const P3& q, const P3& r, double x, double y) {
    const double d = orient(p, q, r);
    const P3 v{x, y, 0};
    return (orient(v, q, r) * p[2] + orient(p, v, r) * q[2] + orient(p, q, v) * r[2]) / d;
  };
  double worst = 0;
  const int c0 = std::max(0, int(std::floor(std::min({a[0], b[0], c[0]})))),
            c1 = std::min(hf.width() - 2, int(std::max({a[0], b[0], c[0]})));
  const int r0 = std::max(0, int(std::floor(std::min({a[1], b[1], c[1]})))),
            r1 = std::min(hf.height() - 2, int(std::max({a[1], b[1], c[1]})));
  for (int j = r0; j <= r1; ++j)
    for (int i = c0; i <= c1; ++i) {
      const P3 s00{double(i), double(j), hf.at(i, j)}, s10{double(i + 1), double(j), hf.at(i + 1, j)};
      const P3 s11{double(i + 1), double(j + 1), hf.at(i + 1, j + 1)},
          s01{double(i), double(j + 1), hf.at(i, j + 1)};
      for (const auto& f : {std::array<P3, 3>{s00, s10, s11}, std::array<P3, 3>{s00, s11, s01}}) {
        std::vector<P3> poly{a, b, c};
        for (int e = 0; e < 3 && !poly.empty(); ++e) {
          const P3& p = f[std::size_t(e)];
          const P3& q = f[std::size_t((e + 1) % 3)];
          std::vector<P3> out;
          for (std::size_t k = 0; k < poly.size(); ++k) {
            const P3& u = poly[k];
            const P3& v = poly[(k + 1) % poly.size()];
            const double su = orient(p, q, u), sv = orient(p, q, v);
            if (su >= 0) out.push_back(u);
            if ((su >= 0) != (sv >= 0)) {
              const double t = su / (su - sv);
              out.push_back({u[0] + t * (v[0] - u[0]), u[1] + t * (v[1] - u[1]), 0});
            }
          }
          poly = out;
        }
        for (const P3& v : poly)
          worst = std::max(worst,
                           std::abs(plane_at(a, b, c, v[0], v[1]) - plane_at(f[0], f[1], f[2], v[0], v[1])));
      }
    }
  return worst;
}

/// Exact single cover of [0,W]x[0,H] and watertightness (tests/support/plane_cover_check.hpp).
std::string check_cover(const hy::HybridMesh& m, double W, double H) {
  return tt::check_plane_cover(m.points, m.triangles, W, H);
}

/// Heights agree: every point of every drawn node has the union vertex's height at its position.
std::size_t height_mismatches(const hy::HybridTree& t, const hy::HybridSelection& s) {
  std::map<std::pair<double, double>, double> z;
  for (const auto& p : s.mesh.points) z[{p[0], p[1]}] = p[2];
  std::size_t bad = 0;
  for (std::int64_t id : s.nodes)
    for (const auto& p : t.tree().node(id).surface.points) {
      auto it = z.find({p[0], p[1]});
      if (it == z.end() || it->second != p[2]) ++bad;
    }
  return bad;
}

/// Triangles as sorted position triples (for comparing meshes with different vertex order).
std::multiset<std::array<std::pair<double, double>, 3>> canon(const hy::HybridMesh& m) {
  std::multiset<std::array<std::pair<double, double>, 3>> out;
  for (const auto& t : m.triangles) {
    std::array<std::pair<double, double>, 3> k;
    for (int i = 0; i < 3; ++i) k[std::size_t(i)] = {m.points[t[i]][0], m.points[t[i]][1]};
    std::rotate(k.begin(), std::min_element(k.begin(), k.end()), k.end());
    out.insert(k);
  }
  return out;
}

/// Camera looking at (col,row) of hf from `dist` metres away, `pitch` degrees down.
pm::Camera camera_at(const pm::Heightfield& hf, double col, double row, double dist, double yaw,
                     double pitch) {
  const auto [x, y] = hf.transform.to_world(col, row);
  const double p = pitch * M_PI / 180, w = yaw * M_PI / 180;
  return pm::Camera{.x = x - dist * std::cos(p) * std::sin(w),
                    .y = y - dist * std::cos(p) * std::cos(w),
                    .z = 60.0 + dist * std::sin(p),
                    .yaw_deg = yaw,
                    .pitch_deg = -pitch,
                    .fovy_deg = 50,
                    .width_px = 800,
                    .height_px = 600,
                    .near_m = 0.5,
                    .far_m = 1e7,
                    .ground = {}};
}

}  // namespace

// Shape: one hybrid chain of `levels` nodes per coarsest cell under a grid quadtree; every node's
// error equals the clipping brute force.
TEST(HybridTree, NodeErrorsEqualBruteForce) {
  const Fixture& f = fixture();
  const auto& t = f.tree.tree();
  EXPECT_EQ(f.tree.cells_x(), 6);
  EXPECT_EQ(f.tree.cell_size(), 16);
  const auto counts = t.count_by_strategy();
  EXPECT_EQ(counts[std::size_t(tb::Strategy::Hybrid)], 36u * 3u);
  // Grid quadtree over 6 x 6 cells from G = 8: 1 + 4 (G = 4) + (4 + 2 + 2 + 1) (G = 2) + 36 = 50.
  EXPECT_EQ(counts[std::size_t(tb::Strategy::Grid)], 50u);
  std::size_t with_tin = 0;
  for (const tb::TreeNode& n : t.nodes()) {
    ASSERT_LE(n.children.size(), 4u);
    double brute = 0;
    for (const auto& tri : n.surface.triangles)
      brute = std::max(brute, brute_triangle_error(f.hf, n.surface.points[tri[0]], n.surface.points[tri[1]],
                                                   n.surface.points[tri[2]]));
    EXPECT_NEAR(n.error, brute, 1e-9 * (1 + brute)) << "node " << n.id;
    if (n.strategy == tb::Strategy::Hybrid && f.tree.grid_level(n.id) == 0) {
      for (const auto& p : n.surface.points) with_tin += p[0] != std::floor(p[0]);
    }
    EXPECT_GE(n.bbox.hi.z, n.bbox.lo.z);
  }
  EXPECT_GT(with_tin, 0u) << "no TIN vertex off the samples in any finest node";
  EXPECT_GT(t.root().error, 0.0);
}

// For random cameras the union of the selection is watertight, covers the domain once, and the
// drawn nodes agree on every shared height. All-hybrid mixes equal extract_mixed exactly.
TEST(HybridTree, RandomSelectionsAreWatertight) {
  const Fixture& f = fixture();
  std::mt19937 rng = terralod::test::printed_seed_rng(20261122);
  std::uniform_real_distribution<double> u(0, 1);
  const double W = f.h.domain_width(), H = f.h.domain_height();
  std::size_t mixed = 0, forced = 0, with_tin = 0, with_grid_and_hybrid = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const pm::Camera cam =
        camera_at(f.hf, u(rng) * W, u(rng) * H, 30 + u(rng) * 3000, u(rng) * 360, 10 + u(rng) * 70);
    const double alpha = 0.25 + u(rng) * 6;
    const hy::HybridSelection s = f.tree.select(pm::View(cam), {.alpha_px = alpha, .cull = false});
    EXPECT_EQ(check_cover(s.mesh, W, H), "") << "trial " << trial;
    EXPECT_EQ(s.height_conflicts, 0u);
    EXPECT_EQ(height_mismatches(f.tree, s), 0u) << "trial " << trial;
    std::set<int> levels(s.cell_level.begin(), s.cell_level.end());
    mixed += levels.size() > 1;
    forced += s.forced > 0;
    with_tin += s.tin_triangles > 0;
    with_grid_and_hybrid += s.grid_nodes > 0 && s.hybrid_nodes > 0;
  }
  std::printf("40 cameras: %zu mixed, %zu forced, %zu with TIN, %zu grid + hybrid\n", mixed, forced, with_tin,
              with_grid_and_hybrid);
  EXPECT_GT(mixed, 5u);
  EXPECT_GT(with_grid_and_hybrid, 3u);
  // Random levels per coarsest cell, all hybrid: the union is extract_mixed's mesh.
  for (int trial = 0; trial < 10; ++trial) {
    std::vector<int> lv(36);
    std::vector<std::int64_t> ids;
    for (auto& l : lv) l = int(u(rng) * 3);
    for (const tb::TreeNode& n : f.tree.tree().nodes())
      if (n.strategy == tb::Strategy::Hybrid) {
        const std::size_t cell = std::size_t(n.domain.row0 / 16 * 6 + n.domain.col0 / 16);
        if (f.tree.grid_level(n.id) == lv[cell]) ids.push_back(n.id);
      }
    ASSERT_EQ(ids.size(), 36u);
    const hy::HybridSelection s = f.tree.assemble(ids);
    EXPECT_EQ(s.cell_level, lv);
    EXPECT_EQ(check_cover(s.mesh, W, H), "");
    EXPECT_EQ(canon(s.mesh), canon(f.h.extract_mixed(lv))) << "trial " << trial;
  }
}

// With frustum culling: no overlap, heights agree, and the only open edges run along the border
// of a coarsest cell that is not drawn (no TIN triangle of a culled cell is missing).
TEST(HybridTree, CulledSelectionsOpenOnlyAtUndrawnCells) {
  const Fixture& f = fixture();
  std::mt19937 rng = terralod::test::printed_seed_rng(977);
  std::uniform_real_distribution<double> u(0, 1);
  const double W = f.h.domain_width(), H = f.h.domain_height(), cs = f.tree.cell_size();
  std::size_t culled_some = 0, added = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const pm::Camera cam =
        camera_at(f.hf, u(rng) * W, u(rng) * H, 30 + u(rng) * 600, u(rng) * 360, 10 + u(rng) * 60);
    const hy::HybridSelection s = f.tree.select(pm::View(cam), {.alpha_px = 0.25 + u(rng) * 4});
    culled_some += s.selection.culled > 0;
    added += s.added;
    EXPECT_EQ(height_mismatches(f.tree, s), 0u);
    std::set<std::pair<std::uint32_t, std::uint32_t>> edges;
    for (const auto& t : s.mesh.triangles) {
      ASSERT_GT(orient(s.mesh.points[t[0]], s.mesh.points[t[1]], s.mesh.points[t[2]]), 0);
      for (int k = 0; k < 3; ++k)
        ASSERT_TRUE(edges.insert({t[k], t[(k + 1) % 3]}).second) << "overlap, trial " << trial;
    }
    auto undrawn = [&](double c, double r) {
      if (c < 0 || r < 0 || c >= W || r >= H) return true;
      return s.cell_level[std::size_t(r / cs) * 6 + std::size_t(c / cs)] == -2;
    };
    for (const auto& [a, b] : edges) {
      if (edges.count({b, a})) continue;
      const auto& p = s.mesh.points[a];
      const auto& q = s.mesh.points[b];
      const double mc = (p[0] + q[0]) / 2, mr = (p[1] + q[1]) / 2;
      bool ok = false;
      if (p[0] == q[0] && std::fmod(p[0], cs) == 0) ok = undrawn(p[0] - 1, mr) || undrawn(p[0] + 1, mr);
      if (p[1] == q[1] && std::fmod(p[1], cs) == 0) ok = ok || undrawn(mc, p[1] - 1) || undrawn(mc, p[1] + 1);
      EXPECT_TRUE(ok) << "trial " << trial << ": open edge (" << p[0] << "," << p[1] << ")-(" << q[0] << ","
                      << q[1] << ")";
    }
  }
  std::printf("40 cameras: %zu with culled nodes, %zu cluster cells added\n", culled_some, added);
  EXPECT_GT(culled_some, 10u);
}

// The closure: one hybrid cell of TIN A with grid everywhere else forces the other cells of A's
// cluster to hybrid, leaves B's cells grid.
TEST(HybridTree, ClusterClosureKeepsTinWhole) {
  const Fixture& f = fixture();
  const auto& t = f.tree.tree();
  // Grid nodes of one coarsest cell (G = 1), except cell (2,2) at hybrid level 0.
  std::vector<std::int64_t> ids;
  for (const tb::TreeNode& n : t.nodes()) {
    if (n.domain.col1 - n.domain.col0 != 16 || n.domain.row1 - n.domain.row0 != 16) continue;
    const bool target = n.domain.col0 == 32 && n.domain.row0 == 32;
    if ((!target && n.strategy == tb::Strategy::Grid) || (target && f.tree.grid_level(n.id) == 0))
      ids.push_back(n.id);
  }
  ASSERT_EQ(ids.size(), 36u);
  const hy::HybridSelection s = f.tree.assemble(ids);
  EXPECT_EQ(check_cover(s.mesh, f.h.domain_width(), f.h.domain_height()), "");
  EXPECT_EQ(s.cell_level[2 * 6 + 2], 0);
  EXPECT_EQ(s.cell_level[1 * 6 + 1], 2) << "a cell of TIN A is forced to the coarsest hybrid level";
  EXPECT_EQ(s.cell_level[5 * 6 + 5], -1) << "TIN B's cells stay grid";
  EXPECT_EQ(s.cell_level[0], -1);
  EXPECT_GT(s.forced, 0u);
  EXPECT_GE(s.tin_triangles, 560u) << "all of A's 560 triangles (more: boundary ones split by the build)";
  EXPECT_LT(s.tin_triangles, f.h.storage_report().tin_triangles) << "B's triangles are not drawn";
}

// A camera just above TIN A: the cell below it is drawn at the finest level and the TIN's
// triangles are in the mesh; far away only grid nodes are drawn.
TEST(HybridTree, TinNearGridFar) {
  const Fixture& f = fixture();
  const double W = f.h.domain_width(), H = f.h.domain_height();
  const hy::HybridSelection near =
      f.tree.select(pm::View(camera_at(f.hf, 40, 30, 60, 30, 45)), {.alpha_px = 1.0, .cull = false});
  EXPECT_EQ(check_cover(near.mesh, W, H), "");
  EXPECT_EQ(near.cell_level[1 * 6 + 2], 0) << "cell (2,1) under the camera";
  EXPECT_GT(near.tin_triangles, 0u);
  // An interior triangle of TIN A (not touched by the build's boundary splits) is drawn as is.
  const auto drawn = canon(near.mesh);
  hy::HybridMesh one;
  one.points = {{31.5, 29.25, 0}, {34, 29.25, 0}, {34, 31.75, 0}};
  one.triangles = {{0, 1, 2}};
  EXPECT_EQ(drawn.count(*canon(one).begin()), 1u);
  std::printf("near: %zu nodes (%zu hybrid), %zu triangles, %zu TIN, forced %zu, error %.3f m\n",
              near.nodes.size(), near.hybrid_nodes, near.mesh.triangles.size(), near.tin_triangles,
              near.forced, near.error_m);

  const hy::HybridSelection far =
      f.tree.select(pm::View(camera_at(f.hf, 48, 48, 2e5, 0, 30)), {.alpha_px = 1.0, .cull = false});
  EXPECT_EQ(check_cover(far.mesh, W, H), "");
  EXPECT_EQ(far.hybrid_nodes, 0u);
  EXPECT_EQ(far.tin_triangles, 0u);
  for (std::int64_t id : far.nodes) EXPECT_EQ(f.tree.tree().node(id).strategy, tb::Strategy::Grid);
  for (int l : far.cell_level) EXPECT_EQ(l, -1);
}

// encode_tree / decode_tree / attach keep every node bit for bit and give the same selection.
TEST(HybridTree, BlobRoundTrip) {
  const Fixture& f = fixture();
  const auto bytes = tb::encode_tree(f.tree.tree());
  const hy::HybridTree back = hy::HybridTree::attach(f.h, tb::decode_tree(bytes, "test tree"), "test tree");
  ASSERT_EQ(back.tree().size(), f.tree.tree().size());
  for (std::size_t i = 0; i < back.tree().size(); ++i) {
    const auto& a = back.tree().nodes()[i];
    const auto& b = f.tree.tree().nodes()[i];
    EXPECT_EQ(a.surface.points, b.surface.points);
    EXPECT_EQ(a.surface.triangles, b.surface.triangles);
    EXPECT_EQ(a.error, b.error);
    EXPECT_EQ(back.grid_level(std::int64_t(i)), f.tree.grid_level(std::int64_t(i)));
  }
  const pm::View view(camera_at(f.hf, 40, 30, 200, 10, 30));
  EXPECT_EQ(canon(back.select(view, {.alpha_px = 2.0}).mesh),
            canon(f.tree.select(view, {.alpha_px = 2.0}).mesh));
  // A tree of another terrain does not attach.
  const hy::HybridTerrain other = hy::HybridTerrain::build(f.hf, f.tin, {.grid_step = 4, .levels = 2});
  EXPECT_THROW(hy::HybridTree::attach(other, tb::decode_tree(bytes, "test tree"), "test tree"),
               hy::HybridError);
}

// The N44W072 valley (the crop of examples/hybrid): watertight near the TIN, TIN drawn there.
TEST(HybridTree, RealValleyN44W072) {
  const std::string dem_path = std::string(TERRALOD_DATA_DIR) + "/N44W072.hgt";
  if (!std::ifstream(dem_path)) GTEST_SKIP() << dem_path << " is absent";
  std::ifstream csv(std::string(TERRALOD_EXAMPLES_DIR) + "/hybrid/valley_N44W072.csv");
  ASSERT_TRUE(csv);
  tt::Valley valley = tt::valley_of(tb::read_dem(dem_path), csv);
  valley.crop.transform = pm::GridTransform::north_up(0, 0, 30, 30);
  const pm::Heightfield& crop = valley.crop;
  const auto h = hy::HybridTerrain::build(crop, tt::valley_tin(valley), {.grid_step = 4, .levels = 3});
  const hy::HybridTree t = hy::HybridTree::build(h, crop);
  const double W = h.domain_width(), H = h.domain_height();
  // Looking along the valley from its northern end, 500 m above it.
  const hy::HybridSelection s =
      t.select(pm::View(camera_at(crop, 100, 40, 1500, 180, 20)), {.alpha_px = 2.0, .cull = false});
  EXPECT_EQ(check_cover(s.mesh, W, H), "");
  EXPECT_EQ(height_mismatches(t, s), 0u);
  EXPECT_GT(s.tin_triangles, 0u);
  EXPECT_GT(s.grid_nodes, 0u);
  EXPECT_NE(std::find(s.cell_level.begin(), s.cell_level.end(), 0), s.cell_level.end());
  std::printf("valley: %zu nodes (%zu hybrid, %zu grid), %zu triangles (%zu TIN), forced %zu\n",
              s.nodes.size(), s.hybrid_nodes, s.grid_nodes, s.mesh.triangles.size(), s.tin_triangles,
              s.forced);
  const auto far =
      t.select(pm::View(camera_at(crop, 100, 180, 5e5, 0, 30)), {.alpha_px = 2.0, .cull = false});
  EXPECT_EQ(far.hybrid_nodes, 0u);
  EXPECT_EQ(check_cover(far.mesh, W, H), "");
}
