// Tests of the fast paths of SelectiveRefinement::update(): the filtered bound pass (float
// boxes of the face prisms, exact evaluation only where the maximum can rise) reports exactly
// the number the full pass over every face gives (SelectiveRefinement::bound_px(view), the
// reference), and the pre-tested tops and frontier give the same selection as a fresh one,
// on random flights over generated and real terrain, with geomorphs, guard bands, absolute
// UTM-sized coordinates and a sheared grid.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <numbers>
#include <random>

#include "refinable_terrain.hpp"
#include "screen_error_checker.hpp"
#include "terralod/pm/selective_refinement.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace pm = terralod::pm;
namespace tt = terralod::test;

namespace {

using Terrain = tt::RefinableTerrain;

pm::Heightfield generated(int size, std::uint64_t seed) {
  pm::TerrainOptions o;
  o.width = o.height = size;
  o.seed = seed;
  return pm::generate_terrain(o);
}

// A flight that exercises frame coherence and its breaks: a random walk (up to two samples
// and two degrees per frame, at a height above the ground that wanders log-uniformly between
// 0.5 m and the terrain's extent, one frame in ten skimming the ground at 0.5 m) with a jump
// to a fresh random pose, looking 5 to 65 degrees down, every 40 frames; near planes from
// 1 mm to 10 m.
std::vector<pm::Camera> random_flight(const pm::Heightfield& hf, int frames, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> U(0.0, 1.0);
  std::vector<pm::Camera> out;
  pm::Camera c;
  const double step = 2.0 * hf.transform.spacing_x();
  const double extent = hf.width() * hf.transform.spacing_x();
  double log_h = 0.0;  // log10 of the height above the ground
  for (int k = 0; k < frames; ++k) {
    if (k % 40 == 0) {
      c = tt::random_pose(hf, rng);
      c.pitch_deg = -5.0 - 60.0 * U(rng);
      c.near_m = std::pow(10.0, -3.0 + 4.0 * U(rng));
      log_h = std::log10(std::max(c.z - tt::ground_height(hf, c.x, c.y), 0.5));
    } else {
      const double yaw = c.yaw_deg * std::numbers::pi / 180.0;
      c.x += step * std::sin(yaw) * U(rng), c.y += step * std::cos(yaw) * U(rng);
      c.yaw_deg += 4.0 * (U(rng) - 0.5);
      c.pitch_deg = std::clamp(c.pitch_deg + 4.0 * (U(rng) - 0.5), -89.0, 0.0);
      log_h = std::clamp(log_h + 0.2 * (U(rng) - 0.5), std::log10(0.5), std::log10(extent));
      c.z = tt::ground_height(hf, c.x, c.y) + (U(rng) < 0.1 ? 0.5 : std::pow(10.0, log_h));
    }
    out.push_back(c);
  }
  return out;
}

struct Counts {
  std::size_t frames = 0, nonzero = 0, morphing = 0, seen_m = 0;
};

// Flies `flight` with `opt` and checks every frame: bound_px equals the full pass bit for bit
// and stays <= tau, bound_m lies between the errors of the faces seen and of all faces; every
// `fresh_every` frames the selection equals a fresh one's.
void fly_and_compare(const pm::CollapseDag& dag, const pm::RefinementOptions& opt,
                     const std::vector<pm::Camera>& flight, int fresh_every, Counts& n) {
  pm::SelectiveRefinement sel(dag, opt);
  double t = 0.0;
  for (std::size_t k = 0; k < flight.size(); ++k, t += 1.0 / 60.0) {
    const pm::View v(flight[k]);
    const pm::FrameStats st = sel.update(v, t);
    ASSERT_EQ(st.bound_px, sel.bound_px(v)) << "frame " << k << " tau " << opt.tolerance_px;
    ASSERT_LE(st.bound_px, st.tolerance_px * (1 + 1e-12)) << "frame " << k;
    // bound_m: at least the error of every face with a corner inside the view (its prism is
    // in view), at most the largest error of the active faces.
    double seen = 0.0, largest = 0.0;
    for (std::uint32_t f : sel.active_faces()) {
      const std::uint32_t c = dag.creator(f);
      const double e = c == pm::CollapseDag::kNone ? 0.0 : dag.collapse(c).error;
      largest = std::max(largest, e);
      for (std::uint32_t s : dag.face(f))
        if (v.contains(dag.position(s))) seen = std::max(seen, e);
    }
    ASSERT_GE(st.bound_m, seen) << "frame " << k;
    ASSERT_LE(st.bound_m, largest) << "frame " << k;
    n.seen_m += seen > 0.0;
    ++n.frames;
    n.nonzero += st.bound_px > 0.0;
    n.morphing += st.morphing > 0;
    if (fresh_every > 0 && k % std::size_t(fresh_every) == 0) {
      pm::RefinementOptions plain = opt;
      plain.morph_seconds = 0.0;
      pm::SelectiveRefinement fresh(dag, plain);
      fresh.update(v);
      ASSERT_EQ(sel.performed_count(), fresh.performed_count()) << "frame " << k;
      for (std::uint32_t c = 0; c < dag.collapse_count(); ++c)
        ASSERT_EQ(sel.performed(c), fresh.performed(c)) << "frame " << k << " collapse " << c;
    }
  }
}

// A generator with a fixed seed, printed so that a failure can be replayed.
std::mt19937_64 seeded(std::uint64_t seed) {
  std::printf("seed %llu\n", static_cast<unsigned long long>(seed));
  return std::mt19937_64(seed);
}

// One random flight at tolerance tau with default options otherwise.
void fly_at(const pm::CollapseDag& dag, double tau, int frames, int fresh_every, std::mt19937_64& rng,
            Counts& n) {
  pm::RefinementOptions o;
  o.tolerance_px = tau;
  fly_and_compare(dag, o, random_flight(dag.heightfield(), frames, rng), fresh_every, n);
}

}  // namespace

// The filtered pass against the full pass, for several tau, guard bands and geomorph modes.
TEST(SelectiveRefinementBound, FilteredBoundEqualsTheFullPassOnRandomFlights) {
  std::mt19937_64 rng = seeded(20261122);
  const Terrain t(generated(129, 7));
  Counts n;
  for (double tau : {0.3, 1.0, 4.0})
    for (double margin : {1.0, 1.5}) {
      pm::RefinementOptions o;
      o.tolerance_px = tau;
      o.cull_margin = margin;
      fly_and_compare(t.dag, o, random_flight(t.hf, 80, rng), /*fresh_every=*/20, n);
    }
  for (pm::MorphMode mode : {pm::MorphMode::Full, pm::MorphMode::Vertical}) {
    pm::RefinementOptions o;
    o.morph_seconds = 0.25;
    o.morph_mode = mode;
    fly_and_compare(t.dag, o, random_flight(t.hf, 120, rng), /*fresh_every=*/0, n);
  }
  std::printf("%zu frames, %zu with a bound > 0, %zu with running geomorphs\n", n.frames, n.nonzero,
              n.morphing);
  EXPECT_GT(n.nonzero, n.frames / 4);  // the comparison is not between zeros
  EXPECT_GT(n.seen_m, n.frames / 4);
  EXPECT_GT(n.morphing, 0u);
}

// The float boxes and the slack hold with UTM-sized coordinates and a sheared, rotated grid.
TEST(SelectiveRefinementBound, FilteredBoundEqualsTheFullPassFarFromTheOrigin) {
  std::mt19937_64 rng = seeded(8);
  pm::Heightfield hf = generated(97, 3);
  hf.transform = pm::GridTransform{612345.5, 29.0, 3.5, 4912345.25, -2.0, -31.0};
  const Terrain t(std::move(hf));
  Counts n;
  fly_at(t.dag, /*tau=*/0.7, /*frames=*/160, /*fresh_every=*/40, rng, n);
  EXPECT_GT(n.nonzero, n.frames / 4);
}

// Spheres keep the per-collapse test (no packed records): the same selection as a fresh one.
TEST(SelectiveRefinementBound, SpheresGiveTheFreshSelection) {
  std::mt19937_64 rng = seeded(11);
  const Terrain t(generated(97, 2), pm::VolumeKind::Sphere);
  Counts n;
  fly_at(t.dag, /*tau=*/0.5, /*frames=*/120, /*fresh_every=*/10, rng, n);
  EXPECT_GT(n.nonzero, n.frames / 8);
}

// Real data: a 257 x 257 crop of N44W072 (the size of the benchmark's blocks).
TEST(SelectiveRefinementBound, FilteredBoundEqualsTheFullPassOnRealTerrain) {
  auto hf = tt::read_hgt_crop("N44W072.hgt", 712, 748, 257);
  if (!hf) GTEST_SKIP() << "N44W072.hgt not found in TERRALOD_DATA_DIR";
  std::mt19937_64 rng = seeded(44);
  const Terrain t(std::move(*hf));
  Counts n;
  for (double tau : {0.5, 2.0}) fly_at(t.dag, tau, /*frames=*/80, /*fresh_every=*/40, rng, n);
  EXPECT_GT(n.nonzero, n.frames / 4);
}
