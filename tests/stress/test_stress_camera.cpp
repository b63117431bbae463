// Numerical stability stress suite (issue 9, part 1), cameras: the view-dependent runtime
// (selection, guaranteed bound, geomorphs) and the OSMesa renderer under hostile cameras.
//
// Cameras: inside the terrain, exactly at the surface, 10 000 km away, looking straight down
// and straight up, fields of view of 1 and 170 degrees, a near plane at 1 mm; tolerances from
// 0.01 px to 10 000 px; terrains at a UTM-sized origin with 1 cm and 1 km spacing, a 10 000 m
// spike on a plain and a vertical cliff. For every case:
//   - the update neither throws nor loops, and the bound it reports is finite and <= tau;
//   - the independent brute-force checker (tests/support/screen_error_checker: GLM matrices,
//     every sample of every triangle, segments clipped to the frustum) measures no
//     in-frustum error above the reported bound;
//   - the active mesh is a valid triangulation (single cover of the domain, no flip);
//   - geomorphing frames display finite positions and no triangle folds over in plan view;
//   - a rendered frame reads back finite depths (or misses) and two renders are identical.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "mesh_checker.hpp"
#include "screen_error_checker.hpp"
#include "terralod/pm/collapse_dag.hpp"
#include "terralod/pm/progressive_mesh.hpp"
#include "terralod/pm/selective_refinement.hpp"
#include "terralod/pm/terrain_generator.hpp"
#include "terralod/pm/view.hpp"
#include "terralod/render/camera.hpp"
#include "terralod/render/draw_mesh.hpp"
#include "terralod/render/gl_context.hpp"
#include "terralod/render/terrain_renderer.hpp"

namespace {

namespace pm = terralod::pm;
namespace rd = terralod::render;
namespace tt = terralod::test;

pm::Heightfield fractal(int size, double spacing, double x0, double y0, double relief) {
  pm::TerrainOptions o;
  o.width = o.height = size;
  o.seed = 29;
  o.relief = relief;
  pm::Heightfield hf = pm::generate_terrain(o);
  hf.transform = pm::GridTransform::north_up(x0, y0, spacing, spacing);
  return hf;
}

struct Terrain {
  std::string name;
  pm::Heightfield hf;
  pm::ProgressiveMesh pm;
  pm::CollapseDag dag;
  explicit Terrain(std::string n, pm::Heightfield h)
      : name(std::move(n)), hf(std::move(h)), pm(pm::ProgressiveMesh::build(hf)), dag(pm) {}
};

const std::vector<std::unique_ptr<Terrain>>& terrains() {
  static const std::vector<std::unique_ptr<Terrain>> t = [] {
    std::printf("terrains: fractal 65 x 65 seed 29 (UTM origin, 1 cm and 1 km), spike, cliff\n");
    std::vector<std::unique_ptr<Terrain>> v;
    v.push_back(std::make_unique<Terrain>("utm_1cm", fractal(65, 0.01, 500000.0, 5000000.0, 0.5)));
    v.push_back(std::make_unique<Terrain>("utm_1km", fractal(65, 1000.0, 500000.0, 5000000.0, 3000.0)));
    pm::Heightfield spike(33, 33);
    spike.at(16, 16) = 10000.0;
    spike.transform = pm::GridTransform::north_up(500000.0, 5000000.0, 30.0, 30.0);
    v.push_back(std::make_unique<Terrain>("spike_10km", std::move(spike)));
    pm::Heightfield cliff(33, 33);
    for (int r = 0; r < 33; ++r)
      for (int c = 0; c < 33; ++c) cliff.at(c, r) = c < 17 ? 0.0 : 500.0 + r;
    cliff.transform = pm::GridTransform::north_up(0.0, 0.0, 10.0, 10.0);
    v.push_back(std::make_unique<Terrain>("cliff_500m", std::move(cliff)));
    return v;
  }();
  return t;
}

struct Extent {
  double cx, cy, size, zmin, zmax;
};

Extent extent(const pm::Heightfield& hf) {
  const auto [x0, y0] = hf.transform.to_world(0, 0);
  const auto [x1, y1] = hf.transform.to_world(hf.width() - 1, hf.height() - 1);
  Extent e{(x0 + x1) / 2, (y0 + y1) / 2, std::max(std::fabs(x1 - x0), std::fabs(y1 - y0)), 1e300, -1e300};
  for (double z : hf.samples()) e.zmin = std::min(e.zmin, z), e.zmax = std::max(e.zmax, z);
  return e;
}

struct CameraCase {
  std::string name;
  pm::Camera cam;
};

// The hostile cameras for one terrain, relative to its extent.
std::vector<CameraCase> cameras(const Terrain& t) {
  const Extent e = extent(t.hf);
  const double ground = tt::ground_height(t.hf, e.cx, e.cy);
  std::vector<CameraCase> v;
  auto add = [&](std::string name, double x, double y, double z, double yaw, double pitch, double fovy,
                 double near_m = 0.01, double far_m = 1e8) {
    pm::Camera c;
    c.x = x, c.y = y, c.z = z, c.yaw_deg = yaw, c.pitch_deg = pitch, c.fovy_deg = fovy;
    c.width_px = 320, c.height_px = 200, c.near_m = near_m, c.far_m = far_m;
    v.push_back({std::move(name), c});
  };
  // Yaw and pitch that look from (x, y, z) at the terrain's centre.
  auto aim = [&](double x, double y, double z, double& yaw, double& pitch) {
    const double dx = e.cx - x, dy = e.cy - y, dz = ground - z;
    yaw = std::atan2(dx, dy) * 180.0 / M_PI;
    pitch = std::atan2(dz, std::hypot(dx, dy)) * 180.0 / M_PI;
  };
  double yaw = 0, pitch = 0;
  const double relief = std::max(e.zmax - e.zmin, 1e-3);
  add("inside_the_terrain", e.cx, e.cy, e.zmin - 0.5 * relief, 30, -10, 60);
  add("at_the_surface", e.cx, e.cy, ground, 45, 0, 60);
  add("at_the_surface_looking_down", e.cx + 0.1 * e.size, e.cy,
      tt::ground_height(t.hf, e.cx + 0.1 * e.size, e.cy), 0, -90, 60);
  aim(e.cx - 7.0e6, e.cy - 7.0e6, 7.0e6, yaw, pitch);
  add("10000_km_away", e.cx - 7.0e6, e.cy - 7.0e6, 7.0e6, yaw, pitch, 60, 1000.0, 1e8);
  add("straight_down", e.cx, e.cy, e.zmax + 0.3 * e.size, 0, -90, 60);
  add("straight_up_from_below", e.cx, e.cy, e.zmin - 0.3 * e.size, 0, 90, 60);
  aim(e.cx - e.size, e.cy - e.size, e.zmax + 0.2 * e.size, yaw, pitch);
  add("fovy_1_degree", e.cx - e.size, e.cy - e.size, e.zmax + 0.2 * e.size, yaw, pitch, 1);
  add("fovy_170_degrees", e.cx, e.cy - 0.2 * e.size, e.zmax + 0.05 * e.size, 0, -30, 170);
  add("near_1_mm", e.cx, e.cy, ground + 0.002, 200, -5, 60, 0.001, 1e7);
  return v;
}

void check_case(const Terrain& t, const CameraCase& cc, double tau, rd::TerrainRenderer* renderer) {
  SCOPED_TRACE(t.name + " / " + cc.name + " / tau " + std::to_string(tau));
  pm::RefinementOptions o;
  o.tolerance_px = tau;
  o.morph_seconds = 0.25;
  pm::SelectiveRefinement sel(t.dag, o);
  // A short approach (5 frames at 60 fps moving towards the final pose) so that geomorphs
  // run, then the pose itself.
  pm::FrameStats st;
  for (int k = 0; k <= 5; ++k) {
    pm::Camera c = cc.cam;
    const double back = 0.02 * extent(t.hf).size * (5 - k);
    c.z += back;
    st = sel.update(pm::View(c), k / 60.0);
    ASSERT_TRUE(std::isfinite(st.bound_px)) << "frame " << k;
    EXPECT_LE(st.bound_px, st.tolerance_px) << "frame " << k;
    const pm::RenderMesh rm = sel.render_mesh();
    std::vector<std::array<double, 3>> idx;
    for (const pm::Vec3& p : rm.positions) {
      ASSERT_TRUE(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) << "frame " << k;
      const auto ij = tt::world_to_index(t.hf, p.x, p.y);
      idx.push_back({ij[0], ij[1], p.z});
    }
    const tt::SurfaceSamples s = tt::surface_at_samples(t.hf, idx, rm.triangles);
    EXPECT_EQ(s.flipped, 0u) << "frame " << k;
  }
  // Geomorphs settled or not, the logical mesh carries the guarantee.
  const pm::TriangleMesh m = sel.mesh();
  const tt::MeshCheck mc = tt::check_mesh(t.hf, m);
  EXPECT_TRUE(mc.topology_ok()) << mc.describe();
  const tt::ScreenCheck sc = tt::check_screen_error(t.hf, m, tt::ScreenProjector(cc.cam));
  EXPECT_TRUE(std::isfinite(sc.max_error_px));
  EXPECT_LE(sc.max_error_px, st.bound_px * (1 + 1e-9) + 1e-9) << sc.describe();
  if (tau == 1.0)
    std::printf(
        "  %-11s %-28s tau 1: %6zu triangles, bound %.3f px, measured %.3f px over %zu visible segments\n",
        t.name.c_str(), cc.name.c_str(), m.triangles.size(), st.bound_px, sc.max_error_px,
        sc.segments_visible);

  if (!renderer) return;
  rd::Camera rc;
  rc.x = cc.cam.x, rc.y = cc.cam.y, rc.z = cc.cam.z;
  rc.yaw_deg = cc.cam.yaw_deg, rc.pitch_deg = cc.cam.pitch_deg, rc.fovy_deg = cc.cam.fovy_deg;
  rc.near_m = cc.cam.near_m, rc.far_m = cc.cam.far_m;
  rc.width_px = cc.cam.width_px, rc.height_px = cc.cam.height_px;
  const rd::MeshId id = renderer->upload(rd::make_draw_mesh(m, t.hf));
  renderer->draw(rc, {{id, 0.0f}});
  const rd::Image a = renderer->read_color();
  const std::vector<rd::DepthSample> d = renderer->read_depth({{0, 0}, {160, 100}, {319, 199}});
  for (const rd::DepthSample& ds : d) EXPECT_FALSE(std::isnan(ds.distance));
  renderer->draw(rc, {{id, 0.0f}});
  EXPECT_TRUE(renderer->read_color() == a) << "two renders of the same frame differ";
  renderer->remove(id);
}

TEST(StressCamera, HostileCamerasKeepTheBoundAndRender) {
  std::unique_ptr<rd::GlContext> ctx;
  std::unique_ptr<rd::TerrainRenderer> renderer;
  try {
    ctx = rd::create_offscreen_context({320, 200});
    renderer = std::make_unique<rd::TerrainRenderer>(*ctx);
  } catch (const std::exception& e) {
    GTEST_FAIL() << "no OSMesa context: " << e.what();
  }
  std::size_t cases = 0;
  for (const auto& t : terrains())
    for (const CameraCase& cc : cameras(*t))
      for (const double tau : {0.01, 1.0, 10000.0}) {
        check_case(*t, cc, tau, tau == 1.0 ? renderer.get() : nullptr);
        ++cases;
      }
  std::printf("%zu camera cases checked\n", cases);
}

// Cameras the View rejects: a clear std::invalid_argument naming the field, never a crash.
TEST(StressCamera, InvalidCamerasAreAClearError) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  struct Bad {
    const char* field;
    pm::Camera cam;
  };
  std::vector<Bad> bad;
  auto make = [&](const char* field, auto mutate) {
    pm::Camera c;
    mutate(c);
    bad.push_back({field, c});
  };
  make("x", [&](pm::Camera& c) { c.x = nan; });
  make("z", [&](pm::Camera& c) { c.z = inf; });
  make("pitch", [&](pm::Camera& c) { c.pitch_deg = 90.5; });
  make("fovy", [&](pm::Camera& c) { c.fovy_deg = 180.0; });
  make("fovy", [&](pm::Camera& c) { c.fovy_deg = 0.0; });
  make("near", [&](pm::Camera& c) { c.near_m = 0.0; });
  make("far", [&](pm::Camera& c) { c.far_m = c.near_m; });
  make("width", [&](pm::Camera& c) { c.width_px = 0; });
  for (const Bad& b : bad) {
    try {
      pm::View v(b.cam);
      ADD_FAILURE() << "accepted a camera with a bad " << b.field;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("view"), std::string::npos) << e.what();
    }
  }
  pm::RefinementOptions o;
  o.tolerance_px = 0.0;
  EXPECT_THROW(pm::SelectiveRefinement(terrains()[2]->dag, o), std::invalid_argument);
  o.tolerance_px = nan;
  EXPECT_THROW(pm::SelectiveRefinement(terrains()[2]->dag, o), std::invalid_argument);
}

}  // namespace
