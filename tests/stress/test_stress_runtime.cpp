// Runtime stress (issue 9, part 1, through blocks::TerrainRuntime): hostile terrains built into
// block databases by build_database, flown over by the runtime along a random flight and a
// script of hostile cameras.
//
// Every frame of every case, either it works with the invariants holding or a clear error is
// given (by the build or by update(): a non-empty message, printed); none crashes or hangs:
//   - no NaN or infinity in any drawn position; the frame's bound is finite and >= 0;
//   - the independent checker (tests/support/drawn_frame_checker) with the same camera: the
//     error of the displayed surface at every sample in view <= the frame's bound (the bound
//     holds for the mesh as drawn, geomorphs included), every sample in view covered, and the
//     mesh watertight (no flipped triangle, no doubled edge, no T-junction, one position per
//     sample, no hole where terrain is in view).
// Terrains (small grids, ASan-friendly): flat, a 10 000 m spike on a plain, a 1000 m cliff
// between two columns, sawtooth, checkerboard, terraces of exactly equal heights, voids filled
// by the DEM reader, fractal terrain in UTM-sized (origin 500 000 m, 5 000 000 m) and degree-sized
// frames with spacings of 1 cm and 1 km, grids of 2 x 2, 2 x 41 and 41 x 2 samples, and prime
// sizes (53 x 47, 37 x 59) that divide into no block size, and a fractal seen through a strong
// ground scale (pm/view.hpp; the checker applies it on its own). Cameras: a random flight (fixed printed
// seed, geomorphs on, blocks arriving while it flies), then straight down, straight up, inside the
// terrain, at the surface, 10 000 km above and 10 000 km away level, fovy 1 and 170 degrees, near
// plane 1 mm, tau 0.01 and 10 000 px (set live, as a viewer does).
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "drawn_frame_checker.hpp"
#include "run_command.hpp"
#include "screen_error_checker.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/terrain_runtime.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace {

namespace fs = std::filesystem;
namespace pm = terralod::pm;
namespace tb = terralod::blocks;
namespace tt = terralod::test;

// ---------------------------------------------------------------------------------------------
// Terrains

struct Terrain {
  std::string name;
  pm::Heightfield hf;
  int block_size = 17;
};

/// Every camera's ground scale over the terrain (a runtime over a continent-wide frame sets one).
pm::GroundScale ground_of(const std::string& name) {
  // Singular values 1.18 and 0.87, far beyond any map projection's.
  return name == "ground_scaled" ? pm::GroundScale{1.1125, 0.1299, 0.9375} : pm::GroundScale{};
}

pm::Heightfield grid(int W, int H, double (*z)(int, int)) {
  pm::Heightfield hf(W, H);
  for (int r = 0; r < H; ++r)
    for (int c = 0; c < W; ++c) hf.at(c, r) = z(c, r);
  hf.transform = pm::GridTransform::north_up(0.0, 30.0 * (H - 1), 30.0, 30.0);
  return hf;
}

pm::Heightfield fractal(int W, int H, std::uint64_t seed, double relief) {
  pm::TerrainOptions to;
  to.width = W, to.height = H, to.seed = seed, to.relief = relief;
  to.quantize_to_metres = true;
  return pm::generate_terrain(to);
}

/// A 41 x 37 ASCII grid with a void, a row of voids and a 5 x 4 hole, read back filled.
pm::Heightfield voids_filled() {
  const fs::path& dir = tt::process_temp_dir("stress-seams");
  const fs::path p = dir / "voids.asc";
  {
    std::ofstream f(p);
    f << "ncols 41\nnrows 37\nxllcorner 500000\nyllcorner 5000000\ncellsize 10\nNODATA_value -9999\n";
    for (int r = 0; r < 37; ++r)
      for (int c = 0; c < 41; ++c) {
        const bool hole = (r == 3 && c == 30) || r == 20 || (c >= 8 && c < 13 && r >= 6 && r < 10);
        f << (hole ? -9999.0 : 200.0 + 3.0 * c - 2.0 * r + 25.0 * std::sin(c * 0.4) * std::cos(r * 0.3))
          << (c + 1 < 41 ? " " : "\n");
      }
  }
  return tb::read_dem(p.string());
}

Terrain terrain(const std::string& name) {
  if (name == "flat") return {name, grid(49, 49, [](int, int) { return 120.0; })};
  if (name == "spike")
    return {name, grid(49, 49, [](int c, int r) { return c == 20 && r == 27 ? 10120.0 : 120.0; })};
  if (name == "cliff") return {name, grid(49, 49, [](int c, int) { return c < 24 ? 0.0 : 1000.0; })};
  if (name == "sawtooth") return {name, grid(49, 33, [](int c, int) { return (c % 2) * 50.0; })};
  if (name == "checkerboard") return {name, grid(33, 49, [](int c, int r) { return ((c + r) % 2) * 100.0; })};
  if (name == "terraces")
    return {name, grid(49, 49, [](int c, int r) {
              return 1000.0 -
                     20.0 * std::floor(std::sqrt(double((c - 24) * (c - 24) + (r - 24) * (r - 24))) / 4.0);
            })};
  if (name == "voids_filled") return {name, voids_filled()};
  if (name == "tiny_2x2") return {name, grid(2, 2, [](int c, int r) { return (c + r) % 2 ? 100.0 : 0.0; })};
  if (name == "thin_2x41")
    return {name, grid(2, 41, [](int c, int r) { return 10.0 * ((c * 7 + r * 13) % 5); })};
  if (name == "thin_41x2")
    return {name, grid(41, 2, [](int c, int r) { return 10.0 * ((c * 7 + r * 13) % 5); })};
  Terrain t{name, fractal(49, 49, 17, 150.0)};
  if (name == "utm_1cm") t.hf.transform = pm::GridTransform::north_up(500000.0, 5000000.0, 0.01, 0.01);
  if (name == "utm_1km") t.hf.transform = pm::GridTransform::north_up(500000.0, 5000000.0, 1000.0, 1000.0);
  if (name == "degrees")
    t.hf.transform = pm::GridTransform::north_up(-72.0, 45.0, 1.0 / 3600.0, 1.0 / 3600.0);
  if (name == "prime_53x47") t = {name, fractal(53, 47, 31, 400.0)};
  if (name == "prime_37x59") t = {name, fractal(37, 59, 37, 400.0), 9};
  if (name == "prime_53x47" || name == "prime_37x59")
    t.hf.transform = pm::GridTransform::north_up(0.0, 30.0 * (t.hf.height() - 1), 30.0, 30.0);
  if (name == "ground_scaled") t.hf.transform = pm::GridTransform::north_up(0.0, 30.0 * 48, 30.0, 30.0);
  return t;
}

// ---------------------------------------------------------------------------------------------
// Cameras

struct Extent {
  double x0, x1, y0, y1, zmin, zmax;
  double cx() const { return 0.5 * (x0 + x1); }
  double cy() const { return 0.5 * (y0 + y1); }
  double size() const { return std::max(x1 - x0, y1 - y0); }
};

Extent extent_of(const pm::Heightfield& hf) {
  Extent e{1e300, -1e300, 1e300, -1e300, 1e300, -1e300};
  for (const auto& [c, r] :
       {std::pair{0, 0}, {hf.width() - 1, 0}, {0, hf.height() - 1}, {hf.width() - 1, hf.height() - 1}}) {
    const auto [x, y] = hf.transform.to_world(c, r);
    e.x0 = std::min(e.x0, x), e.x1 = std::max(e.x1, x), e.y0 = std::min(e.y0, y), e.y1 = std::max(e.y1, y);
  }
  for (const double z : hf.samples()) e.zmin = std::min(e.zmin, z), e.zmax = std::max(e.zmax, z);
  return e;
}

struct Shot {
  std::string name;
  pm::Camera cam;
  double tau = 1.0;
};

/// The hostile script, in the terrain's own scale (s: its size; top: its highest sample).
std::vector<Shot> hostile_cameras(const pm::Heightfield& hf) {
  const Extent e = extent_of(hf);
  const double s = e.size(), top = e.zmax, cx = e.cx(), cy = e.cy();
  auto cam = [&](double x, double y, double z, double yaw, double pitch, double fovy = 60.0) {
    pm::Camera c;
    c.x = x, c.y = y, c.z = z, c.yaw_deg = yaw, c.pitch_deg = pitch, c.fovy_deg = fovy;
    c.width_px = 320, c.height_px = 240;
    c.near_m = std::max(1e-3, 1e-4 * s);
    c.far_m = 1e5 * std::max(1.0, s + (top - e.zmin));
    return c;
  };
  const double g = tt::ground_height(hf, cx + 0.13 * s, cy - 0.11 * s);
  std::vector<Shot> v = {
      {"oblique", cam(cx - 0.2 * s, cy - 0.6 * s, top + 0.4 * s, 10, -30)},
      {"straight_down", cam(cx, cy, top + 0.5 * s, 0, -90)},
      {"straight_up", cam(cx + 0.1 * s, cy, top + 0.3 * s, 45, 90)},
      {"inside_terrain", cam(cx + 0.13 * s, cy - 0.11 * s, g - 0.05 * s - 1.0, 200, -10)},
      {"at_surface", cam(cx + 0.13 * s, cy - 0.11 * s, g, 30, 0)},
      {"10000km_above", cam(cx, cy, top + 1e7, 0, -90)},
      {"10000km_away_level", cam(cx, cy - 1e7, top, 0, 0)},
      {"fovy_1", cam(cx - 0.1 * s, cy - 0.7 * s, top + 0.3 * s, 5, -20, 1.0)},
      {"fovy_170", cam(cx, cy - 0.2 * s, top + 0.1 * s, 0, -40, 170.0)},
      {"near_1mm", cam(cx, cy - 0.3 * s, top + 0.2 * s, 0, -35)},
      {"tau_0.01", cam(cx - 0.2 * s, cy - 0.6 * s, top + 0.4 * s, 10, -30), 0.01},
      {"tau_10000", cam(cx - 0.2 * s, cy - 0.6 * s, top + 0.4 * s, 10, -30), 10000.0},
  };
  v[9].cam.near_m = 1e-3;
  v[9].cam.far_m = 1e7;
  v[5].cam.far_m = 1e8;
  v[6].cam.far_m = 1e8;
  return v;
}

/// A random low flight over the terrain (seeded): constant speed, random turns, looking ahead.
std::vector<pm::Camera> random_flight(const pm::Heightfield& hf, std::uint64_t seed, int frames) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  const Extent e = extent_of(hf);
  const double s = e.size();
  double x = e.x0 + (e.x1 - e.x0) * (0.2 + 0.6 * u(rng)), y = e.y0 + (e.y1 - e.y0) * (0.2 + 0.6 * u(rng));
  double heading = 2 * M_PI * u(rng), turn = 0;
  std::vector<pm::Camera> path;
  for (int f = 0; f < frames; ++f) {
    if (f % 10 == 0) turn = (u(rng) - 0.5) * 6;
    heading += turn / 60;
    x = std::clamp(x + 0.01 * s * std::sin(heading), e.x0, e.x1);
    y = std::clamp(y + 0.01 * s * std::cos(heading), e.y0, e.y1);
    pm::Camera c;
    c.x = x, c.y = y;
    c.z = tt::ground_height(hf, x, y) + (0.02 + 0.3 * u(rng)) * s + 0.01 * (e.zmax - e.zmin);
    c.yaw_deg = heading * 180 / M_PI;
    c.pitch_deg = -10 - 50 * u(rng);
    c.width_px = 320, c.height_px = 240;
    c.near_m = std::max(1e-3, 1e-4 * s);
    c.far_m = 1e5 * std::max(1.0, s + (e.zmax - e.zmin));
    path.push_back(c);
  }
  return path;
}

// ---------------------------------------------------------------------------------------------
// The checks

struct Counts {
  std::size_t frames = 0, pm_frames = 0, stitched = 0, moving = 0, errors = 0;
  double worst_ratio = 0;  // measured / bound
};

/// Checks one frame; returns false after a failure (the caller stops the flight).
bool check_frame(const tb::TerrainRuntime& rt, const pm::Heightfield& hf, const pm::Camera& cam,
                 const std::string& label, Counts& n) {
  const tb::RuntimeFrameStats& st = rt.stats();
  ++n.frames;
  n.pm_frames += st.pm_blocks > 0;
  n.stitched += st.seam_triangles > 0;
  n.moving += st.moving_vertices > 0;
  const tb::DrawnMesh& m = rt.drawn_mesh();
  for (const pm::Vec3& p : m.positions)
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
      ADD_FAILURE() << label << ": drawn position (" << p.x << ", " << p.y << ", " << p.z
                    << ") is not finite";
      return false;
    }
  if (!std::isfinite(st.bound_px) || st.bound_px < 0) {
    ADD_FAILURE() << label << ": bound " << st.bound_px << " px";
    return false;
  }
  tt::DrawnFrame f;
  f.samples = m.samples;
  for (const pm::Vec3& p : m.positions) f.z.push_back(p.z);
  f.triangles = m.triangles;
  const tt::FrameCheck c = tt::check_drawn_frame(hf, f, cam);
  if (!c.watertight() || c.uncovered_in_view > 0 || c.max_error_px > st.bound_px * (1 + 1e-9) + 1e-9) {
    ADD_FAILURE() << label << " (" << st.pm_blocks << " PM blocks, " << st.standin_blocks << " stand-ins, "
                  << st.missing_in_view << " missing, " << st.moving_vertices << " moving vertices): bound "
                  << st.bound_px << " px; " << c.describe();
    return false;
  }
  if (st.bound_px > 0) n.worst_ratio = std::max(n.worst_ratio, c.max_error_px / st.bound_px);
  return true;
}

/// Flies `shots` (each held `hold` frames so that loads arrive and the selection settles) with
/// one runtime; tau is changed live where a shot asks for another.
void fly(const std::string& db, const pm::Heightfield& hf, const std::vector<Shot>& shots, int hold,
         double morph_s, const std::string& label, Counts& n) {
  tb::RuntimeOptions opt;
  opt.morph_seconds = morph_s;
  std::unique_ptr<tb::TerrainRuntime> rt;
  try {
    rt = std::make_unique<tb::TerrainRuntime>(db, opt);
  } catch (const std::exception& e) {
    ADD_FAILURE() << label << ": the runtime refused the database: " << e.what();
    return;
  }
  double time = 0;
  for (const Shot& shot : shots) {
    if (shot.tau != rt->options().tolerance_px) {
      opt.tolerance_px = shot.tau;
      rt->set_options(opt);
    }
    for (int f = 0; f < hold; ++f, time += 1.0 / 60) {
      const std::string where = label + " " + shot.name + " frame " + std::to_string(f);
      try {
        rt->update(pm::View(shot.cam), time);
      } catch (const std::exception& e) {
        // A clear error is an accepted outcome; an empty message is not.
        ++n.errors;
        std::printf("  %s: error: %s\n", where.c_str(), e.what());
        EXPECT_GT(std::string(e.what()).size(), 10u) << where;
        break;
      }
      if (!check_frame(*rt, hf, shot.cam, where, n)) return;
      // The loader gets the processor too; on the script, the blocks a shot needs arrive
      // within its frames.
      rt->wait_for_loader(hold > 1 ? 0.05 : 0.001);
    }
  }
}

void run_terrain(const std::string& name) {
  const Terrain tr = terrain(name);
  const auto t0 = std::chrono::steady_clock::now();
  const std::string db = (tt::process_temp_dir("stress-runtime") / (name + ".db")).string();
  try {
    tb::DatabaseBuildOptions o;
    o.block_size = tr.block_size;
    o.threads = 1;
    tb::build_database(tr.hf, db, o);
  } catch (const std::exception& e) {
    // Building the database may refuse a terrain, with a clear message.
    std::printf("%s: refused: %s\n", name.c_str(), e.what());
    EXPECT_GT(std::string(e.what()).size(), 10u) << name;
    return;
  }
  const std::uint64_t seed = 0x5EA5 + std::hash<std::string>{}(name) % 1000;
  std::printf("%s: %d x %d samples, blocks of %d, random flight seed %llu\n", name.c_str(), tr.hf.width(),
              tr.hf.height(), tr.block_size, static_cast<unsigned long long>(seed));
  Counts n;
  std::vector<Shot> flight;
  for (pm::Camera c : random_flight(tr.hf, seed, 40)) {
    c.ground = ground_of(name);
    flight.push_back({"random", c});
  }
  fly(db, tr.hf, flight, 1, /*morph_s=*/0.3, name, n);
  std::vector<Shot> script = hostile_cameras(tr.hf);
  for (Shot& shot : script) shot.cam.ground = ground_of(name);
  fly(db, tr.hf, script, 6, /*morph_s=*/0.0, name, n);
  std::printf(
      "  %zu frames checked (%zu with PM blocks, %zu stitched, %zu with moving vertices; worst "
      "measured/bound "
      "%.3f), %zu clear errors, %.0f ms; cameras:",
      n.frames, n.pm_frames, n.stitched, n.moving, n.worst_ratio, n.errors,
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  for (const Shot& s : script) std::printf(" %s", s.name.c_str());
  std::printf("\n");
  // A plain, one spike or one cliff (each caught by a block's 64-point TIN stand-in) and grids 2
  // samples wide are drawn within tau by coarse nodes and stand-ins alone; every other terrain
  // needs PM blocks, so the checks saw them.
  const bool coarse_suffice =
      name == "flat" || name == "spike" || name == "cliff" || tr.hf.width() < 3 || tr.hf.height() < 3;
  if (!coarse_suffice) {
    EXPECT_GT(n.pm_frames, 0u)
        << "no PM block was ever drawn: the checks saw only coarse nodes and stand-ins";
  }
}

class StressRuntime : public ::testing::TestWithParam<std::string> {};

TEST_P(StressRuntime, EveryFrameWatertightCoveredFiniteAndWithinItsBound) { run_terrain(GetParam()); }

INSTANTIATE_TEST_SUITE_P(Hostile, StressRuntime,
                         ::testing::Values("flat", "spike", "cliff", "sawtooth", "checkerboard", "terraces",
                                           "voids_filled", "tiny_2x2", "thin_2x41", "thin_41x2", "utm_1cm",
                                           "utm_1km", "degrees", "prime_53x47", "prime_37x59",
                                           "ground_scaled"),
                         [](const ::testing::TestParamInfo<std::string>& i) { return i.param; });

}  // namespace
