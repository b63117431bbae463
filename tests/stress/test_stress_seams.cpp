// Seam stress (issue 9, part 1, through the streaming pipeline of issue 5): hostile terrains cut
// into blocks (session fixture: every block's PM built and encoded as in a block database),
// flown over by blocks::TerrainSession along a random flight and a script of hostile cameras.
//
// Every frame of every case, either it works with the invariants holding or update() gives a
// clear error (a non-empty message, printed); none crashes or hangs:
//   - watertight: check_watertight of the session fixture (interior edges used once each way,
//     boundary edges only on the active region's border, no T-junction, plan-view area equal to
//     the region's, one position per sample, no triangle flipped or degenerate in plan view);
//   - no NaN or infinity in any drawn position;
//   - the frame's bound is finite and >= 0, and, on the script (no geomorph: morph_seconds = 0,
//     so the drawn mesh is the logical one), >= the screen-space error measured by the
//     independent brute-force checker (tests/support/screen_error_checker) with the same camera.
// Terrains (small grids, ASan-friendly): flat, a 10 000 m spike on a plain, a 1000 m cliff
// between two columns, sawtooth, checkerboard, terraces of exactly equal heights, voids filled
// by the DEM reader, fractal terrain in UTM-sized (origin 500 000 m, 5 000 000 m) and degree-sized
// frames with spacings of 1 cm and 1 km, grids of 2 x 2, 2 x 41 and 41 x 2 samples, and prime
// sizes (53 x 47, 37 x 59) that divide into no block size. Cameras: a random flight (fixed printed seed, geomorphs on), then straight down,
// straight up, inside the terrain, at the surface, 10 000 km above and 10 000 km away level,
// fovy 1 and 170 degrees, near plane 1 mm, tau 0.01 and 10 000 px.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "../blocks/session_fixture.hpp"
#include "run_command.hpp"
#include "screen_error_checker.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/terrain_session.hpp"
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
  if (name == "spike") return {name, grid(49, 49, [](int c, int r) { return c == 20 && r == 27 ? 10120.0 : 120.0; })};
  if (name == "cliff") return {name, grid(49, 49, [](int c, int) { return c < 24 ? 0.0 : 1000.0; })};
  if (name == "sawtooth") return {name, grid(49, 33, [](int c, int) { return (c % 2) * 50.0; })};
  if (name == "checkerboard") return {name, grid(33, 49, [](int c, int r) { return ((c + r) % 2) * 100.0; })};
  if (name == "terraces")
    return {name, grid(49, 49, [](int c, int r) {
              return 1000.0 - 20.0 * std::floor(std::sqrt(double((c - 24) * (c - 24) + (r - 24) * (r - 24))) / 4.0);
            })};
  if (name == "voids_filled") return {name, voids_filled()};
  if (name == "tiny_2x2") return {name, grid(2, 2, [](int c, int r) { return (c + r) % 2 ? 100.0 : 0.0; })};
  if (name == "thin_2x41") return {name, grid(2, 41, [](int c, int r) { return 10.0 * ((c * 7 + r * 13) % 5); })};
  if (name == "thin_41x2") return {name, grid(41, 2, [](int c, int r) { return 10.0 * ((c * 7 + r * 13) % 5); })};
  Terrain t{name, fractal(49, 49, 17, 150.0)};
  if (name == "utm_1cm") t.hf.transform = pm::GridTransform::north_up(500000.0, 5000000.0, 0.01, 0.01);
  if (name == "utm_1km") t.hf.transform = pm::GridTransform::north_up(500000.0, 5000000.0, 1000.0, 1000.0);
  if (name == "degrees") t.hf.transform = pm::GridTransform::north_up(-72.0, 45.0, 1.0 / 3600.0, 1.0 / 3600.0);
  if (name == "prime_53x47") t = {name, fractal(53, 47, 31, 400.0)};
  if (name == "prime_37x59") t = {name, fractal(37, 59, 37, 400.0), 9};
  if (name == "prime_53x47" || name == "prime_37x59")
    t.hf.transform = pm::GridTransform::north_up(0.0, 30.0 * (t.hf.height() - 1), 30.0, 30.0);
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
  for (const auto& [c, r] : {std::pair{0, 0}, {hf.width() - 1, 0}, {0, hf.height() - 1}, {hf.width() - 1, hf.height() - 1}}) {
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
  std::size_t frames = 0, measured = 0, refined_frames = 0, stitched = 0, morphing = 0, errors = 0;
  double worst_ratio = 0;  // measured / bound
};

/// Checks one frame; returns false after a failure (the caller stops the flight).
bool check_frame(const tb::TerrainSession& s, const tb::SessionFrameStats& st, const tt::BlockedTerrain& t,
                 const pm::Camera& cam, bool measure, const std::string& label, Counts& n) {
  ++n.frames;
  n.refined_frames += st.refined > 0;
  n.stitched += st.seam_triangles > 0;
  n.morphing += st.morphing_blocks > 0;
  const tb::DrawnMesh& m = s.drawn_mesh();
  for (const pm::Vec3& p : m.positions)
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
      ADD_FAILURE() << label << ": drawn position (" << p.x << ", " << p.y << ", " << p.z << ") is not finite";
      return false;
    }
  if (!std::isfinite(st.bound_px) || st.bound_px < 0) {
    ADD_FAILURE() << label << ": bound " << st.bound_px << " px";
    return false;
  }
  const tt::WatertightCheck w = tt::check_watertight(m, s.grid(), tt::region_rect(s));
  if (!w.ok()) {
    ADD_FAILURE() << label << " (" << st.refined << " refined, " << st.stand_ins << " stand-ins, "
                  << st.morphing_blocks << " morphing): " << w.describe();
    return false;
  }
  if (!measure) return true;
  // The logical mesh (no geomorph running): vertices are samples at their true heights.
  pm::TriangleMesh sm;
  for (std::size_t v = 0; v < m.positions.size(); ++v) {
    const std::uint64_t k = m.samples[v];
    if (k == tb::DrawnMesh::kNoSample || m.positions[v].z != t.hf[std::size_t(k)]) {
      ADD_FAILURE() << label << ": vertex " << v << " is not a sample at its height with morph_seconds = 0";
      return false;
    }
    sm.vertices.push_back(std::uint32_t(k));
  }
  sm.triangles = m.triangles;
  const tt::ScreenCheck c = tt::check_screen_error(t.hf, sm, tt::ScreenProjector(cam));
  ++n.measured;
  if (c.max_error_px > st.bound_px * (1 + 1e-9) + 1e-9) {
    ADD_FAILURE() << label << ": measured " << c.describe() << " > bound " << st.bound_px << " px";
    return false;
  }
  if (st.bound_px > 0) n.worst_ratio = std::max(n.worst_ratio, c.max_error_px / st.bound_px);
  return true;
}

/// Flies `shots` (each held `hold` frames so that loads arrive and the selection settles).
void fly(const tt::BlockedTerrain& t, const std::vector<Shot>& shots, int hold, double morph_s, bool measure,
         const std::string& label, Counts& n) {
  tt::MemoryStore store;
  store.terrain = &t;
  tb::SessionOptions opt;
  opt.refinement.morph_seconds = morph_s;
  std::unique_ptr<tb::TerrainSession> s;
  try {
    s = std::make_unique<tb::TerrainSession>(tt::memory_source(store), t.grid, t.summaries, opt);
  } catch (const std::exception& e) {
    ADD_FAILURE() << label << ": the session refused the terrain: " << e.what();
    return;
  }
  const tt::ReleaseAtExit release{store};
  double time = 0;
  for (const Shot& shot : shots) {
    // tau changes per shot: a fresh session would reload everything, so it is set through a
    // session per tau only when it differs (the script keeps tau = 1 except its last two).
    if (shot.tau != s->options().refinement.tolerance_px) {
      s.reset();
      opt.refinement.tolerance_px = shot.tau;
      s = std::make_unique<tb::TerrainSession>(tt::memory_source(store), t.grid, t.summaries, opt);
    }
    for (int f = 0; f < hold; ++f, time += 1.0 / 60) {
      const std::string where = label + " " + shot.name + " frame " + std::to_string(f);
      const tb::SessionFrameStats* st = nullptr;
      try {
        st = &s->update(pm::View(shot.cam), time);
      } catch (const std::exception& e) {
        // A clear error is an accepted outcome; an empty message is not.
        ++n.errors;
        std::printf("  %s: error: %s\n", where.c_str(), e.what());
        EXPECT_GT(std::string(e.what()).size(), 10u) << where;
        break;
      }
      store.advance_frame();
      if (!check_frame(*s, *st, t, shot.cam, measure, where, n)) return;
      std::this_thread::sleep_for(std::chrono::milliseconds(1));  // the loader gets the processor too
    }
  }
}

void run_terrain(const std::string& name) {
  const Terrain tr = terrain(name);
  const auto t0 = std::chrono::steady_clock::now();
  tt::BlockedTerrain t;
  try {
    t = tt::block_terrain(tr.hf, tr.block_size);
  } catch (const std::exception& e) {
    // Cutting into blocks and building their PMs may refuse a terrain, with a clear message.
    std::printf("%s: refused: %s\n", name.c_str(), e.what());
    EXPECT_GT(std::string(e.what()).size(), 10u) << name;
    return;
  }
  const std::uint64_t seed = 0x5EA5 + std::hash<std::string>{}(name) % 1000;
  std::printf("%s: %d x %d samples, blocks of %d (%d x %d), random flight seed %llu\n", name.c_str(), t.hf.width(),
              t.hf.height(), tr.block_size, t.grid.cols(), t.grid.rows(), static_cast<unsigned long long>(seed));
  Counts n;
  std::vector<Shot> flight;
  for (const pm::Camera& c : random_flight(t.hf, seed, 40)) flight.push_back({"random", c});
  fly(t, flight, 1, /*morph_s=*/0.3, /*measure=*/false, name, n);
  const std::vector<Shot> script = hostile_cameras(t.hf);
  fly(t, script, 6, /*morph_s=*/0.0, /*measure=*/true, name, n);
  std::printf("  %zu frames (%zu with refined blocks, %zu stitched, %zu mid-geomorph), %zu measured against their "
              "bound (worst measured/bound %.3f), %zu clear errors, %.0f ms; cameras:",
              n.frames, n.refined_frames, n.stitched, n.morphing, n.measured, n.worst_ratio, n.errors,
              std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  for (const Shot& s : script) std::printf(" %s", s.name.c_str());
  std::printf("\n");
  EXPECT_GT(n.refined_frames, 0u) << "no block was ever refined: the checks saw only stand-ins";
}

class StressSeams : public ::testing::TestWithParam<std::string> {};

TEST_P(StressSeams, EveryFrameWatertightFiniteAndWithinItsBound) { run_terrain(GetParam()); }

INSTANTIATE_TEST_SUITE_P(Hostile, StressSeams,
                         ::testing::Values("flat", "spike", "cliff", "sawtooth", "checkerboard", "terraces",
                                           "voids_filled", "tiny_2x2", "thin_2x41", "thin_41x2", "utm_1cm", "utm_1km", "degrees", "prime_53x47",
                                           "prime_37x59"),
                         [](const ::testing::TestParamInfo<std::string>& i) { return i.param; });

}  // namespace
