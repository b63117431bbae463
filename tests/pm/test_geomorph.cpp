// Tests of geomorphs: the static M^G(alpha) between two selections (exact endpoints, no flips,
// pointwise blend, watertight overlay), and runtime geomorphs during a flight (they end
// bit-identical to the selection without geomorphs; per-frame surface change with and without;
// no fold in plan view).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <random>

#include "mesh_checker.hpp"
#include "refinable_terrain.hpp"
#include "screen_error_checker.hpp"
#include "terralod/pm/geomorph.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace pm = terralod::pm;
namespace tt = terralod::test;

namespace {

using Terrain = tt::RefinableTerrain;

const Terrain& generated(int size, std::uint64_t seed) { return tt::generated_refinable(size, seed); }

// Plan positions in index space (col, row) and heights of a render mesh.
std::vector<std::array<double, 3>> to_index(const pm::Heightfield& hf, const pm::RenderMesh& m) {
  std::vector<std::array<double, 3>> p;
  p.reserve(m.positions.size());
  for (const pm::Vec3& v : m.positions) {
    const auto ij = tt::world_to_index(hf, v.x, v.y);
    p.push_back({ij[0], ij[1], v.z});
  }
  return p;
}

// Height of M (sample-vertex mesh) at a point given in index space, by brute-force location
// (long double barycentric weights); NaN when no triangle holds it.
double height_at(const pm::Heightfield& hf, const pm::TriangleMesh& m, double col, double row) {
  const std::uint32_t W = std::uint32_t(hf.width());
  for (const auto& t : m.triangles) {
    long double x[3], y[3], z[3];
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t s = m.vertices[t[k]];
      x[k] = s % W, y[k] = s / W, z[k] = hf[s];
    }
    const long double A = (x[1] - x[0]) * (y[2] - y[0]) - (y[1] - y[0]) * (x[2] - x[0]);
    const long double w0 = ((x[1] - col) * (y[2] - row) - (y[1] - row) * (x[2] - col)) / A;
    const long double w1 = ((x[2] - col) * (y[0] - row) - (y[2] - row) * (x[0] - col)) / A;
    const long double w2 = 1 - w0 - w1;
    if (w0 < -1e-12L || w1 < -1e-12L || w2 < -1e-12L) continue;
    return double(w0 * z[0] + w1 * z[1] + w2 * z[2]);
  }
  return NAN;
}

}  // namespace

// M^G(0) is M^A and M^G(1) is M^B: every vertex lies on the surface it starts (ends) on,
// M^A's own vertices bit for bit; the surface agrees at every sample; no triangle flips or
// degenerates in plan view; the overlay is watertight (every interior edge used twice,
// opposite ways) and its area is the domain's.
TEST(StaticGeomorph, EndpointsAreExactAndNothingFlips) {
  const Terrain& t = generated(129, 5);
  std::mt19937_64 rng(61);
  std::printf("seed 61\n");
  double worst_vertex = 0, worst_sample = 0;
  std::size_t pairs = 0, steiner = 0, tris = 0, larger = 0;
  for (int k = 0; k < 25; ++k) {
    pm::SelectiveRefinement a(t.dag), b(t.dag);
    a.update(pm::View(tt::random_pose(t.hf, rng)));
    b.update(pm::View(tt::random_pose(t.hf, rng)));
    const pm::Geomorph g = pm::make_geomorph(a, b);
    ++pairs, tris += g.triangles.size(), larger += std::max(a.triangle_count(), b.triangle_count());
    const pm::TriangleMesh ma = a.mesh(), mb = b.mesh();
    // Vertices: samples of M^A keep their height exactly; every vertex is on both surfaces.
    std::vector<std::uint8_t> in_a(t.hf.size(), 0), in_b(t.hf.size(), 0);
    for (std::uint32_t s : ma.vertices) in_a[s] = 1;
    for (std::uint32_t s : mb.vertices) in_b[s] = 1;
    for (std::size_t i = 0; i < g.plan.size(); ++i) {
      const std::uint32_t s = g.samples[i];
      if (s == pm::Geomorph::kNoSample) ++steiner;
      if (s != pm::Geomorph::kNoSample && in_a[s]) {
        ASSERT_EQ(g.z_from[i], t.hf[s]);
      }
      if (s != pm::Geomorph::kNoSample && in_b[s]) {
        ASSERT_EQ(g.z_to[i], t.hf[s]);
      }
      if (i % 41 != 0) continue;  // brute-force location is slow: every 41st vertex
      const double za = height_at(t.hf, ma, g.plan[i][0], g.plan[i][1]);
      const double zb = height_at(t.hf, mb, g.plan[i][0], g.plan[i][1]);
      worst_vertex = std::max({worst_vertex, std::abs(za - g.z_from[i]), std::abs(zb - g.z_to[i])});
    }
    // The surfaces at every sample.
    for (const double alpha : {0.0, 1.0}) {
      const pm::RenderMesh m = g.at(alpha);
      const pm::RenderMesh ref = alpha == 0 ? a.render_mesh() : b.render_mesh();
      const tt::SurfaceSamples s = tt::surface_at_samples(t.hf, to_index(t.hf, m), m.triangles);
      const tt::SurfaceSamples r = tt::surface_at_samples(t.hf, to_index(t.hf, ref), ref.triangles);
      for (std::size_t i = 0; i < t.hf.size(); ++i)
        worst_sample = std::max(worst_sample, std::abs(s.height[i] - r.height[i]));
    }
    // Plan view: positive orientation (doubles, as drawn), watertight, area of the domain.
    long double area = 0;
    std::map<std::pair<std::uint32_t, std::uint32_t>, int> edges;
    for (const auto& tri : g.triangles) {
      const auto &p = g.plan[tri[0]], &q = g.plan[tri[1]], &r = g.plan[tri[2]];
      const double o = (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]);
      ASSERT_GT(o, 0.0) << "flipped or degenerate triangle in pair " << k;
      area += o;
      for (int e = 0; e < 3; ++e) ++edges[{tri[e], tri[(e + 1) % 3]}];
    }
    EXPECT_NEAR(double(area), 2.0 * 128 * 128, 1e-6);
    for (const auto& [e, n] : edges) {
      ASSERT_EQ(n, 1);
      if (!edges.count({e.second, e.first})) {  // a boundary edge lies on the grid border
        const auto &p = g.plan[e.first], &q = g.plan[e.second];
        const bool border = (p[0] == 0 && q[0] == 0) || (p[0] == 128 && q[0] == 128) ||
                            (p[1] == 0 && q[1] == 0) || (p[1] == 128 && q[1] == 128);
        ASSERT_TRUE(border) << "open edge inside the domain: T-junction or gap";
      }
    }
  }
  std::printf(
      "%zu pairs: overlay %.2f x the larger mesh, %zu crossing vertices; worst |z - surface| at vertices "
      "%.3g m, at samples %.3g m\n",
      pairs, double(tris) / double(larger), steiner, worst_vertex, worst_sample);
  EXPECT_LT(worst_vertex, 1e-9);
  EXPECT_LT(worst_sample, 1e-9);
}

// Between the ends, M^G(alpha) is the pointwise blend (1 - alpha) M^A + alpha M^B.
TEST(StaticGeomorph, IsThePointwiseBlend) {
  const Terrain& t = generated(129, 5);
  std::mt19937_64 rng(62);
  for (int k = 0; k < 5; ++k) {
    pm::SelectiveRefinement a(t.dag), b(t.dag);
    a.update(pm::View(tt::random_pose(t.hf, rng)));
    b.update(pm::View(tt::random_pose(t.hf, rng)));
    const pm::Geomorph g = pm::make_geomorph(a, b);
    const pm::RenderMesh ra = a.render_mesh(), rb = b.render_mesh();
    const auto sa = tt::surface_at_samples(t.hf, to_index(t.hf, ra), ra.triangles);
    const auto sb = tt::surface_at_samples(t.hf, to_index(t.hf, rb), rb.triangles);
    for (const double alpha : {0.25, 0.5, 0.8}) {
      const pm::RenderMesh m = g.at(alpha);
      const auto s = tt::surface_at_samples(t.hf, to_index(t.hf, m), m.triangles);
      EXPECT_EQ(s.flipped + s.degenerate, 0u);
      for (std::size_t i = 0; i < t.hf.size(); ++i)
        ASSERT_NEAR(s.height[i], (1 - alpha) * sa.height[i] + alpha * sb.height[i], 1e-9);
    }
  }
  pm::SelectiveRefinement a(t.dag);
  EXPECT_THROW(pm::make_geomorph(a, a).at(1.5), std::invalid_argument);
  const pm::CollapseDag other(t.pm);
  pm::SelectiveRefinement c(other);
  EXPECT_THROW(pm::make_geomorph(a, c), std::invalid_argument);
}

namespace {

struct FlightChange {
  double worst_all = 0, worst_vertices = 0;  // largest per-frame change, pixels
  double p99_all = 0, median_all = 0;
  std::size_t flips = 0, max_morphing = 0, pending = 0;
  // Per-vertex check of the morph time: a vertex present in two consecutive frames moves
  // vertically by at most |jump| * dt / T of the geomorph it is in (or its anchor's), and not
  // at all when no geomorph moves it. speed_ratio = the largest measured / allowed.
  double speed_ratio = 0, max_duration = 0;
  std::size_t moved_at_rest = 0, vertex_frames = 0;
};

// Vertical change allowed per frame of length dt for the vertex at `sample`: from the
// geomorph it (or the vertex it rides on) is in, |to.z - from.z| * dt / (t1 - t0).
double allowed_change(const std::map<std::uint32_t, pm::SelectiveRefinement::MorphState>& morphs,
                      std::uint32_t sample, double dt) {
  for (int hops = 0; hops < 64; ++hops) {
    const auto it = morphs.find(sample);
    if (it == morphs.end()) return 0.0;
    const auto& m = it->second;
    if (m.anchor != pm::CollapseDag::kNone) {
      sample = m.anchor;
      continue;
    }
    return std::abs(m.to[2] - m.from[2]) * dt / (m.t1 - m.t0);
  }
  return 0.0;
}

// Flies `frames` frames at 60 fps with the given options; for every frame the change of the
// displayed surface at every sample since the previous frame, as a vertical segment projected
// with the current camera (independent GLM projector, clipped to the frustum).
FlightChange fly(const Terrain& t, const pm::RefinementOptions& o, const std::vector<pm::Camera>& flight,
                 pm::SelectiveRefinement** keep = nullptr) {
  static std::unique_ptr<pm::SelectiveRefinement> last;
  last = std::make_unique<pm::SelectiveRefinement>(t.dag, o);
  pm::SelectiveRefinement& sel = *last;
  FlightChange r;
  std::vector<double> prev, per_frame;
  std::vector<std::uint8_t> was_vertex(t.hf.size(), 0), is_vertex(t.hf.size(), 0);
  std::map<std::uint32_t, double> prev_z;  // displayed height of each vertex, last frame
  std::map<std::uint32_t, pm::SelectiveRefinement::MorphState> prev_morphs;
  const double dt = 1.0 / 60.0;
  for (std::size_t k = 0; k < flight.size(); ++k) {
    const pm::FrameStats& st = sel.update(pm::View(flight[k]), double(k) / 60.0);
    std::map<std::uint32_t, pm::SelectiveRefinement::MorphState> morphs;
    for (const auto& m : sel.morph_states()) {
      morphs[m.sample] = m;
      if (m.anchor == pm::CollapseDag::kNone) r.max_duration = std::max(r.max_duration, m.t1 - m.t0);
    }
    r.max_morphing = std::max(r.max_morphing, st.morphing);
    r.pending = std::max(r.pending, st.pending_ecols);
    const pm::RenderMesh m = sel.render_mesh();
    std::map<std::uint32_t, double> z_now;
    for (std::size_t v = 0; v < m.samples.size(); ++v) {
      z_now[m.samples[v]] = m.positions[v].z;
      const auto before = prev_z.find(m.samples[v]);
      if (k == 0 || before == prev_z.end()) continue;
      // The geomorph it was in at the last frame, or one that started at this update (which
      // starts from where the vertex was displayed, so the earlier one bounds the change).
      const double allowed =
          std::max(allowed_change(prev_morphs, m.samples[v], dt), allowed_change(morphs, m.samples[v], dt));
      const double change = std::abs(m.positions[v].z - before->second);
      ++r.vertex_frames;
      if (allowed == 0.0)
        r.moved_at_rest += change > 0.0;
      else
        r.speed_ratio = std::max(r.speed_ratio, change / allowed);
    }
    prev_z = std::move(z_now);
    prev_morphs = std::move(morphs);
    const tt::SurfaceSamples s = tt::surface_at_samples(t.hf, to_index(t.hf, m), m.triangles);
    r.flips += s.flipped;
    std::fill(is_vertex.begin(), is_vertex.end(), 0);
    for (std::uint32_t v : m.samples) is_vertex[v] = 1;
    if (k > 0) {
      const tt::ScreenProjector proj(flight[k]);
      double worst = 0;
      for (int row = 0; row < t.hf.height(); ++row)
        for (int col = 0; col < t.hf.width(); ++col) {
          const std::size_t i = std::size_t(row) * t.hf.width() + col;
          const auto [x, y] = t.hf.transform.to_world(col, row);
          const double px = proj.vertical_segment_px(x, y, prev[i], s.height[i]);
          worst = std::max(worst, px);
          if (is_vertex[i] || was_vertex[i]) r.worst_vertices = std::max(r.worst_vertices, px);
        }
      per_frame.push_back(worst);
      r.worst_all = std::max(r.worst_all, worst);
    }
    prev = s.height;
    std::swap(was_vertex, is_vertex);
  }
  std::sort(per_frame.begin(), per_frame.end());
  r.median_all = per_frame[per_frame.size() / 2];
  r.p99_all = per_frame[per_frame.size() * 99 / 100];
  if (keep) *keep = &sel;
  return r;
}

}  // namespace

// Per-frame change of the displayed surface during a flight (tau = 1 px, a guard band of 1.5):
// without geomorphs every vsplit and ecol pops, by up to about tau and more. With the default
// full geomorphs nothing pops: every sample's height changes continuously, each slide over the
// morph time, and no triangle folds over in plan view (slides are scheduled so that none
// can). Vertical geomorphs (heights only) cannot fold either and change slowly at the
// vertices, but between vertices a vsplit still changes the surface at once: the new
// triangles cross the old ones' creases (printed, for the record).
TEST(RuntimeGeomorph, PerFrameChangeWithAndWithoutGeomorphs) {
  const Terrain& t = generated(257, 3);
  const auto flight = tt::scripted_flight(t.hf, 2400, 150, -15, 1.0);  // ~170 m/s at 60 fps
  const std::vector<pm::Camera> frames(flight.begin(), flight.begin() + 160);
  pm::RefinementOptions o;
  o.cull_margin = 1.5;  // a guard band: terrain turning into view is already refined
  const FlightChange none = fly(t, o, frames);
  o.morph_seconds = 0.5;
  const FlightChange full = fly(t, o, frames);
  o.morph_mode = pm::MorphMode::Vertical;
  const FlightChange vertical = fly(t, o, frames);
  auto line = [](const char* name, const FlightChange& c) {
    std::printf(
        "%-26s per-frame change at all samples: max %.3f, p99 %.3f, median %.3f px; at vertices max "
        "%.3f px; folded triangle-frames %zu; vertices morphing at most %zu\n",
        name, c.worst_all, c.p99_all, c.median_all, c.worst_vertices, c.flips, c.max_morphing);
  };
  line("no geomorph", none);
  line("full geomorph 0.5 s", full);
  line("vertical geomorph 0.5 s", vertical);
  EXPECT_EQ(none.flips + full.flips + vertical.flips, 0u);
  EXPECT_GT(full.max_morphing, 0u);
  EXPECT_GT(full.pending, 0u);
  EXPECT_GT(none.worst_all, 0.9);
  EXPECT_LT(full.worst_all, 0.25 * none.worst_all);
  EXPECT_LT(full.p99_all, 0.25 * none.p99_all);
  EXPECT_LT(vertical.worst_vertices, 0.25 * none.worst_vertices);
  // Bounded by the morph time: every vertex moves at most its jump * dt / T per frame, no
  // geomorph lasts longer than T, and vertices outside geomorphs do not move.
  for (const FlightChange* c : {&full, &vertical}) {
    std::printf(
        "per-vertex change / (jump * dt / T): worst %.6f over %zu vertex-frames; longest morph %.3f s\n",
        c->speed_ratio, c->vertex_frames, c->max_duration);
    EXPECT_LE(c->speed_ratio, 1.0 + 1e-6);
    EXPECT_GT(c->speed_ratio, 0.5);  // the check saw real motion
    EXPECT_LE(c->max_duration, o.morph_seconds + 1e-9);
    EXPECT_EQ(c->moved_at_rest, 0u);
  }
}

// The same on real terrain, with a short and a long morph time: far smaller than the pops,
// and no fold.
TEST(RuntimeGeomorph, RealTerrainFlight) {
  auto hf = tt::read_hgt_crop("N44W072.hgt", 712, 748, 257);
  if (!hf) GTEST_SKIP() << "N44W072.hgt not in " << TERRALOD_DATA_DIR;
  const Terrain real(std::move(*hf));
  const auto path = tt::scripted_flight(real.hf, 4800, 100, -15, 1.0);
  const std::vector<pm::Camera> frames(path.begin(), path.begin() + 120);
  pm::RefinementOptions o;
  o.cull_margin = 1.5;
  const FlightChange none = fly(real, o, frames);
  for (const double T : {0.25, 1.0}) {
    o.morph_seconds = T;
    const FlightChange full = fly(real, o, frames);
    std::printf(
        "N44W072 crop, morph %.2f s: per-frame change max %.3f px (p99 %.3f) against %.3f px (p99 %.3f) "
        "without geomorphs; folded triangle-frames %zu\n",
        T, full.worst_all, full.p99_all, none.worst_all, none.p99_all, full.flips);
    EXPECT_EQ(full.flips, 0u);
    EXPECT_LT(full.worst_all, 0.4 * none.worst_all);
  }
}

// Coarsening morphs u into the coarse surface before the collapse takes effect, one level per
// morph time; once the camera stops, the running geomorphs end exactly where the selection
// without geomorphs is: same faces, positions bit for bit.
TEST(RuntimeGeomorph, EndsBitIdenticalToTheSelectionWithoutGeomorphs) {
  const Terrain& t = generated(129, 5);
  pm::RefinementOptions o;
  o.morph_seconds = 0.5;
  pm::SelectiveRefinement sel(t.dag, o);
  // 5 km above the middle, looking down (the whole terrain in view), then 15 km: coarsens,
  // all of it in view.
  pm::Camera c;
  const auto [x, y] = t.hf.transform.to_world(64, 64);
  c.x = x, c.y = y, c.pitch_deg = -90, c.z = 5000;
  double time = 0;
  sel.update(pm::View(c), time);
  const std::size_t refined = sel.performed_count();
  c.z = 15000;
  const pm::View far(c);
  const pm::FrameStats s0 = sel.update(far, time += 0.01);
  EXPECT_EQ(s0.ecols, 0u) << "every collapse is in view: none may happen before its morph";
  EXPECT_GT(s0.pending_ecols, 0u);
  // Halfway: pending vertices are halfway down, nothing collapsed yet.
  const pm::FrameStats s1 = sel.update(far, time += 0.25);
  EXPECT_EQ(s1.ecols, 0u);
  EXPECT_EQ(sel.performed_count(), refined);
  const pm::FrameStats s2 = sel.update(far, time += 0.26);
  EXPECT_GT(s2.ecols, 0u);
  int steps = 0;
  while (sel.morphing() && steps < 1000) sel.update(far, time += 1.0 / 60), ++steps;
  std::printf("coarsening settled after %.2f s (%d frames)\n", time, steps);
  ASSERT_FALSE(sel.morphing());
  pm::SelectiveRefinement plain(t.dag);
  plain.update(far);
  const pm::TriangleMesh a = sel.mesh(), b = plain.mesh();
  EXPECT_EQ(a.vertices, b.vertices);
  EXPECT_EQ(a.triangles, b.triangles);
  const pm::RenderMesh ra = sel.render_mesh(), rb = plain.render_mesh();
  ASSERT_EQ(ra.positions.size(), rb.positions.size());
  for (std::size_t i = 0; i < ra.positions.size(); ++i) {
    ASSERT_EQ(ra.positions[i].x, rb.positions[i].x);
    ASSERT_EQ(ra.positions[i].y, rb.positions[i].y);
    ASSERT_EQ(ra.positions[i].z, rb.positions[i].z);
  }
  // The same after a flight with refinements and coarsenings in flight when it stops.
  const auto flight = tt::scripted_flight(t.hf, 1200, 80, -20, 1.0);
  pm::SelectiveRefinement f(t.dag, o);
  for (std::size_t k = 0; k < 120; ++k) f.update(pm::View(flight[k]), double(k) / 60);
  EXPECT_TRUE(f.morphing());
  double tf = 2.0;
  while (f.morphing()) f.update(pm::View(flight[119]), tf += 1.0 / 60);
  pm::SelectiveRefinement g(t.dag);
  g.update(pm::View(flight[119]));
  EXPECT_EQ(f.mesh().triangles, g.mesh().triangles);
  const pm::RenderMesh rf = f.render_mesh(), rg = g.render_mesh();
  for (std::size_t i = 0; i < rf.positions.size(); ++i) ASSERT_EQ(rf.positions[i].z, rg.positions[i].z);
}
