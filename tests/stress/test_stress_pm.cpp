// Numerical stability stress suite (issue 9, part 1): hostile terrains, coordinates and grid
// sizes through build -> extract -> encode/decode -> vertex hierarchy -> world-unit PLY.
//
// Every case either works with the invariants holding or gives a clear error:
//   - bound: every extraction's error, measured by the independent brute-force checker
//     (tests/support/mesh_checker) at every sample and at every crossing of a mesh edge with
//     a grid edge, is within the bound extract() reports, which is within the requested E;
//   - coverage and watertightness: single cover of the domain, no flipped or degenerate
//     triangle in plan view (index space), and none flipped in the world frame either;
//   - no NaN/inf anywhere: bounds, collapse errors, hierarchy errors and radii, world
//     positions; world x/y written to PLY are exactly hf.transform.to_world(col, row) and
//     read back bit for bit (UTM-sized origins with 1 cm spacing keep their precision);
//   - lossless: decode_pm(encode_pm(pm)) == pm, and its extractions are the same meshes.
// Randomised terrains use a fixed seed, printed.
#include <gdal_priv.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "build_threads.hpp"
#include "dag_hierarchy_check.hpp"
#include "mesh_checker.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/pm/collapse_dag.hpp"
#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/mesh_io.hpp"
#include "terralod/pm/pm_io.hpp"
#include "terralod/pm/progressive_mesh.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace {

namespace fs = std::filesystem;
namespace pm = terralod::pm;
namespace tb = terralod::blocks;
namespace tt = terralod::test;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

fs::path tmp_file(const std::string& name) {
  const fs::path dir = fs::path(TERRALOD_TEST_TMP) / "stress_pm";
  fs::create_directories(dir);
  return dir / name;
}

// ------------------------------------------------------------------------------------------
// The pipeline and its invariants

struct PipelineOptions {
  pm::ErrorMetric metric = pm::ErrorMetric::Continuous;
  int threads = 1;
  /// Errors to extract at besides 0, fractions of the largest collapse error, and 1e300.
  std::vector<double> errors;
};

struct PipelineResult {
  pm::ProgressiveMesh pm;
  std::vector<std::pair<double, pm::TriangleMesh>> meshes;  // (E, extract(E))
};

/// World-frame checks of one extraction: finite positions, equal to to_world(col, row) exactly,
/// CCW seen from above, and a PLY round trip that gives the same bits.
void check_world_mesh(const pm::Heightfield& hf, const pm::TriangleMesh& m, const std::string& label,
                      bool write_ply) {
  const pm::TriangleMeshData w = pm::mesh_positions(m, hf, pm::Units::World);
  ASSERT_EQ(w.positions.size(), m.vertices.size());
  const pm::GridTransform& t = hf.transform;
  const auto W = std::uint32_t(hf.width());
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    const double col = double(m.vertices[i] % W), row = double(m.vertices[i] / W);
    const auto& p = w.positions[i];
    ASSERT_TRUE(std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]))
        << label << " vertex " << i;
    // Exactly the affine map, evaluated in double as the header writes it.
    ASSERT_EQ(p[0], t.x0 + col * t.xc + row * t.xr) << label;
    ASSERT_EQ(p[1], t.y0 + col * t.yc + row * t.yr) << label;
    if (t.xr == 0.0 && t.yc == 0.0) {  // north-up: x = x0 + col * dx exactly
      ASSERT_EQ(p[0], t.x0 + col * t.xc) << label;
      ASSERT_EQ(p[1], t.y0 + row * t.yr) << label;
    }
    ASSERT_EQ(p[2], hf[m.vertices[i]]) << label;
  }
  // No triangle flipped in the world frame (coordinates relative to the first corner, so that a
  // UTM-sized origin does not eat the area of a 1 cm triangle).
  std::size_t flipped = 0;
  for (const auto& tri : w.triangles) {
    const auto &a = w.positions[tri[0]], &b = w.positions[tri[1]], &c = w.positions[tri[2]];
    const double area2 = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    flipped += !(area2 > 0.0);
  }
  EXPECT_EQ(flipped, 0u) << label << ": triangles not CCW seen from above in the world frame";

  if (write_ply) {
    const fs::path path = tmp_file(label + ".ply");
    pm::write_mesh(m, hf, path.string(), pm::Units::World);
    const pm::TriangleMeshData back = pm::read_ply(path.string());
    ASSERT_EQ(back.positions.size(), w.positions.size()) << label;
    for (std::size_t i = 0; i < w.positions.size(); ++i)
      for (int k = 0; k < 3; ++k)
        ASSERT_EQ(std::bit_cast<std::uint64_t>(back.positions[i][std::size_t(k)]),
                  std::bit_cast<std::uint64_t>(w.positions[i][std::size_t(k)]))
            << label << " PLY vertex " << i;
    EXPECT_EQ(back.triangles, w.triangles) << label;
    fs::remove(path);
  }
}

// The hierarchy the runtime builds on load (the collapse DAG), with boxes and with spheres:
// saturated errors, nested volumes holding their created faces, corners and borders kept.
void check_hierarchy(const pm::ProgressiveMesh& p, const std::string& label) {
  for (pm::VolumeKind kind : {pm::VolumeKind::Box, pm::VolumeKind::Sphere}) {
    const pm::CollapseDag dag(p, {kind});
    EXPECT_EQ(terralod::test::dag_hierarchy_violation(dag), "")
        << label << (kind == pm::VolumeKind::Box ? " (boxes)" : " (spheres)");
  }
}

/// Equality bit for bit (operator== compares heights with ==, so a NaN under the mask, where
/// a hole's height is not terrain, would make a PM unequal to itself).
bool same_bits(const pm::ProgressiveMesh& a, const pm::ProgressiveMesh& b) {
  const pm::Heightfield &ha = a.heightfield(), &hb = b.heightfield();
  if (ha.size() != hb.size() || ha.width() != hb.width() || ha.mask() != hb.mask() ||
      !(ha.transform == hb.transform) || a.metric() != b.metric() || a.error_quantum() != b.error_quantum() ||
      a.collapses() != b.collapses() || a.dropped_faces() != b.dropped_faces() || ha.source != hb.source)
    return false;
  for (std::size_t i = 0; i < ha.size(); ++i)
    if (std::bit_cast<std::uint64_t>(ha[i]) != std::bit_cast<std::uint64_t>(hb[i])) return false;
  return true;
}

/// Runs the whole pipeline on `hf` and checks every invariant; returns the PM and meshes for
/// case-specific assertions.
PipelineResult run_pipeline(const pm::Heightfield& hf, const std::string& label,
                            const PipelineOptions& o = {}) {
  pm::BuildOptions bo;
  bo.metric = o.metric;
  bo.threads = o.threads;
  const auto t0 = std::chrono::steady_clock::now();
  PipelineResult r{pm::ProgressiveMesh::build(hf, bo), {}};
  const pm::ProgressiveMesh& p = r.pm;
  const double build_ms = ms_since(t0);

  EXPECT_TRUE(std::isfinite(p.max_error())) << label;
  // Triangles interpolate sample heights, so no error can exceed the range of the valid heights.
  double lo = kInf, hi = -kInf;
  for (std::size_t i = 0; i < hf.size(); ++i)
    if (hf.valid(i)) lo = std::min(lo, hf[i]), hi = std::max(hi, hf[i]);
  if (lo <= hi) {
    EXPECT_LE(p.max_error(), (hi - lo) * (1 + 1e-12) + p.error_quantum()) << label;
  }
  for (const pm::Collapse& c : p.collapses()) {
    if (!std::isfinite(c.error) || !(c.error >= 0.0)) {
      ADD_FAILURE() << label << ": collapse error " << c.error;
      break;
    }
  }

  std::vector<double> errors = {
      0.0, p.max_error() / 1000, p.max_error() / 10, p.max_error() / 2, p.max_error(), 1e300};
  errors.insert(errors.end(), o.errors.begin(), o.errors.end());
  std::sort(errors.begin(), errors.end());
  errors.erase(std::unique(errors.begin(), errors.end()), errors.end());

  tt::CheckOptions co;
  co.excluded_faces = p.dropped_faces();
  const bool continuous = o.metric == pm::ErrorMetric::Continuous;
  std::size_t previous = SIZE_MAX;
  for (double E : errors) {
    SCOPED_TRACE(label + ", E = " + std::to_string(E));
    pm::TriangleMesh m = p.extract(E);
    EXPECT_TRUE(std::isfinite(m.error_bound));
    EXPECT_LE(m.error_bound, E);
    EXPECT_LE(m.triangles.size(), previous) << "triangle count grew with E";
    previous = m.triangles.size();
    const tt::MeshCheck c = tt::check_mesh(hf, m, co);
    EXPECT_TRUE(c.topology_ok()) << c.describe();
    EXPECT_TRUE(c.ok(m.error_bound, continuous)) << "error above the reported bound " << m.error_bound << "\n"
                                                 << c.describe();
    EXPECT_TRUE(std::isfinite(c.max_sample_error) && std::isfinite(c.max_crossing_error));
    check_world_mesh(hf, m, label, /*write_ply=*/E == p.max_error() / 10);
    r.meshes.emplace_back(E, std::move(m));
  }

  // Lossless serialization: same PM, same meshes.
  const std::vector<std::uint8_t> bytes = pm::encode_pm(p);
  const pm::ProgressiveMesh back = pm::decode_pm(bytes, label + ".pm");
  EXPECT_TRUE(same_bits(back, p)) << label << ": decode(encode(pm)) differs";
  EXPECT_EQ(pm::encode_pm(back), bytes) << label << ": re-encoding differs";
  for (const auto& [E, m] : r.meshes) {
    const pm::TriangleMesh b = back.extract(E);
    EXPECT_EQ(b.vertices, m.vertices) << label << " E=" << E;
    EXPECT_EQ(b.triangles, m.triangles) << label << " E=" << E;
    EXPECT_EQ(b.error_bound, m.error_bound) << label << " E=" << E;
  }
  check_hierarchy(p, label);

  std::printf(
      "  %-28s %4d x %-4d build %6.1f ms, %7zu collapses, max error %-10.6g, E=0: %zu tris, "
      "base: %zu tris, %zu bytes\n",
      label.c_str(), hf.width(), hf.height(), build_ms, p.vsplit_count(), p.max_error(),
      r.meshes.front().second.triangles.size(), r.meshes.back().second.triangles.size(), bytes.size());
  return r;
}

bool has_vertex(const pm::TriangleMesh& m, int col, int row, int W) {
  return std::find(m.vertices.begin(), m.vertices.end(), std::uint32_t(row * W + col)) != m.vertices.end();
}

pm::Heightfield make(int W, int H, double (*z)(int, int), const std::string& source) {
  pm::Heightfield hf(W, H);
  for (int r = 0; r < H; ++r)
    for (int c = 0; c < W; ++c) hf.at(c, r) = z(c, r);
  hf.source = source;
  return hf;
}

pm::Heightfield fractal(int W, int H, std::uint64_t seed, double relief = 300.0) {
  pm::TerrainOptions to;
  to.width = W, to.height = H, to.seed = seed, to.relief = relief;
  std::printf("  fractal %d x %d, seed %llu\n", W, H, (unsigned long long)seed);
  pm::Heightfield hf = pm::generate_terrain(to);
  hf.source = "fractal " + std::to_string(W) + "x" + std::to_string(H);
  return hf;
}

// ------------------------------------------------------------------------------------------
// Coordinates and spacings: UTM-sized and geographic-degree origins, 1 cm to 1 km spacing.

struct Frame {
  const char* name;
  double x0, y0, spacing;
};

std::ostream& operator<<(std::ostream& o, const Frame& f) { return o << f.name; }

class StressFrames : public ::testing::TestWithParam<Frame> {};

TEST_P(StressFrames, PipelineHoldsAndWorldPositionsAreExact) {
  const Frame f = GetParam();
  pm::Heightfield hf = fractal(49, 37, 17, /*relief=*/150.0);
  hf.transform = pm::GridTransform::north_up(f.x0, f.y0, f.spacing, f.spacing);
  const PipelineResult r = run_pipeline(hf, f.name);

  // Precision: neighbouring samples are `spacing` apart in the world frame to 1e-9 relative
  // (doubles at 5e6 m resolve 1e-9 m), and no two samples share a position.
  const pm::TriangleMesh& full = r.meshes.front().second;
  const pm::TriangleMeshData w = pm::mesh_positions(full, hf, pm::Units::World);
  std::vector<std::pair<double, double>> xy;
  for (const auto& p : w.positions) xy.emplace_back(p[0], p[1]);
  std::sort(xy.begin(), xy.end());
  EXPECT_EQ(std::unique(xy.begin(), xy.end()) - xy.begin(), std::ptrdiff_t(xy.size()));
  for (int c = 0; c + 1 < hf.width(); ++c) {
    const double d = hf.transform.to_world(c + 1, 5).first - hf.transform.to_world(c, 5).first;
    ASSERT_NEAR(d, f.spacing, 1e-9 * std::max(1.0, std::fabs(f.x0)) + 1e-9 * f.spacing) << "col " << c;
  }
  for (int row = 0; row + 1 < hf.height(); ++row) {
    const double d = hf.transform.to_world(3, row).second - hf.transform.to_world(3, row + 1).second;
    ASSERT_NEAR(d, f.spacing, 1e-9 * std::max(1.0, std::fabs(f.y0)) + 1e-9 * f.spacing) << "row " << row;
  }
  // The error bound is vertical: it does not depend on the frame.
  pm::Heightfield unit = hf;
  unit.transform = pm::GridTransform::identity();
  const pm::ProgressiveMesh q = pm::ProgressiveMesh::build(unit, tt::build_threads(1));
  EXPECT_EQ(q.collapses(), r.pm.collapses()) << "the collapse sequence depends on the world frame";
}

INSTANTIATE_TEST_SUITE_P(
    Stress, StressFrames,
    ::testing::Values(Frame{"origin0_1cm", 0.0, 0.0, 0.01}, Frame{"origin0_1km", 0.0, 0.0, 1000.0},
                      Frame{"utm_1cm", 500000.0, 5000000.0, 0.01}, Frame{"utm_1m", 500000.0, 5000000.0, 1.0},
                      Frame{"utm_1km", 500000.0, 5000000.0, 1000.0},
                      // Degrees taken as units (a geographic grid not mapped to metres): 3 arc-seconds.
                      Frame{"degrees_3arcsec", -72.0, 45.0, 1.0 / 1200.0},
                      Frame{"degrees_1arcsec_south_east", 179.5, -89.5, 1.0 / 3600.0}),
    [](const ::testing::TestParamInfo<Frame>& i) { return std::string(i.param.name); });

// ------------------------------------------------------------------------------------------
// Hostile shapes

TEST(StressShapes, FlatTerrainIsTwoTrianglesAtZeroError) {
  // Every collapse ties at error 0; the builder must still finish and reach the corners.
  for (const double z : {0.0, 8848.25, -432.5}) {
    pm::Heightfield hf(33, 33);
    for (double& v : hf.samples()) v = z;
    hf.transform = pm::GridTransform::north_up(500000.0, 5000000.0, 0.01, 0.01);
    const PipelineResult r = run_pipeline(hf, "flat_" + std::to_string(int(z)));
    const pm::TriangleMesh& m = r.meshes.front().second;  // E = 0
    EXPECT_EQ(m.error_bound, 0.0);
    EXPECT_EQ(r.pm.max_error(), 0.0);
    EXPECT_EQ(m.triangles.size(), 2u) << "flat terrain at E=0 should be the two corner triangles";
    EXPECT_EQ(m.vertices.size(), 4u);
  }
}

TEST(StressShapes, SpikeOf10000MetresOnAPlainIsKeptBelowItsHeight) {
  // A single sample 10 000 m above a flat plain at 120 m, in the interior, on the west border
  // and next to a corner. Removing it costs exactly its height above the plain, so every
  // extraction with E < 10 000 keeps it, and the base mesh's bound is 10 000.
  for (const auto& [sc, sr] : std::vector<std::pair<int, int>>{{32, 27}, {0, 20}, {1, 1}}) {
    pm::Heightfield hf(65, 55);
    for (double& v : hf.samples()) v = 120.0;
    hf.at(sc, sr) = 10120.0;
    hf.transform = pm::GridTransform::north_up(500000.0, 5000000.0, 30.0, 30.0);
    const std::string label = "spike_" + std::to_string(sc) + "_" + std::to_string(sr);
    PipelineOptions o;
    o.errors = {1.0, 5000.0, 9999.0, 9999.999, 10000.0};
    const PipelineResult r = run_pipeline(hf, label, o);
    for (const auto& [E, m] : r.meshes) {
      if (E < 10000.0) {
        EXPECT_TRUE(has_vertex(m, sc, sr, 65)) << label << ": E=" << E << " lost the spike";
      }
    }
    EXPECT_EQ(r.pm.max_error(), 10000.0) << label;
    EXPECT_EQ(r.pm.extract(1e300).triangles.size(), 2u) << label;
  }
}

TEST(StressShapes, VerticalCliffs) {
  // A 1000 m step between neighbouring columns, a diagonal step, and a step between rows.
  auto step_x = [](int c, int) { return c < 24 ? 0.0 : 1000.0; };
  auto step_diag = [](int c, int r) { return c + r < 40 ? 3.0 : 503.0; };
  auto step_y = [](int, int r) { return r < 11 ? -50.0 : 2500.0; };
  for (const auto& [name, f] :
       {std::pair{"cliff_x", +step_x}, {"cliff_diag", +step_diag}, {"cliff_y", +step_y}}) {
    pm::Heightfield hf = make(48, 36, f, name);
    hf.transform = pm::GridTransform::north_up(500000.0, 5000000.0, 1.0, 1.0);
    const PipelineResult r = run_pipeline(hf, name);
    // The full grid is kept only where the step is: E = 0 still simplifies the flat sides.
    EXPECT_LT(r.meshes.front().second.triangles.size(), std::size_t(2 * 47 * 35)) << name;
  }
}

TEST(StressShapes, SawtoothCheckerboardAndWhiteNoise) {
  const std::uint32_t seed = 90210;
  std::printf("  white noise seed %u\n", seed);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1000.0, 1000.0);
  pm::Heightfield noise(41, 29);
  for (double& v : noise.samples()) v = u(rng);
  noise.source = "white noise";
  const std::vector<std::pair<std::string, pm::Heightfield>> cases = {
      {"sawtooth_x", make(
                         41, 29, [](int c, int) { return (c % 2) * 50.0; }, "sawtooth")},
      {"sawtooth_y", make(
                         41, 29, [](int, int r) { return (r % 2) * 50.0; }, "sawtooth")},
      {"sawtooth_ramp", make(
                            41, 29, [](int c, int r) { return (c % 4) * 10.0 + r; }, "sawtooth ramp")},
      {"checkerboard", make(
                           41, 29, [](int c, int r) { return ((c + r) % 2) * 100.0; }, "checkerboard")},
      {"white_noise", noise},
  };
  for (const auto& [name, hf] : cases) {
    run_pipeline(hf, name);
    PipelineOptions samples;
    samples.metric = pm::ErrorMetric::Samples;
    run_pipeline(hf, name + "_samples", samples);
  }
}

TEST(StressShapes, TerracesOfExactlyEqualHeights) {
  // Concentric terraces 20 m high, 4 samples wide: large tied plateaus with sharp edges.
  const pm::Heightfield hf = make(
      61, 47,
      [](int c, int r) {
        const double d = std::sqrt(double((c - 30) * (c - 30) + (r - 23) * (r - 23)));
        return 1000.0 - 20.0 * std::floor(d / 4.0);
      },
      "terraces");
  const PipelineResult r = run_pipeline(hf, "terraces");
  EXPECT_LE(r.pm.max_error(), 1000.0);
  // Ties at E = 0: the plateaus simplify, the terrace edges stay.
  EXPECT_LT(r.meshes.front().second.triangles.size(), std::size_t(2 * 60 * 46));
}

TEST(StressShapes, TinyReliefAtHighAltitude) {
  // Millimetre relief at 4000 m: errors of 1e-3 m must not drown in the rounding of 4000.
  const std::uint32_t seed = 4242;
  std::printf("  tiny relief seed %u\n", seed);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1e-3);
  pm::Heightfield hf(33, 33);
  for (double& v : hf.samples()) v = 4000.0 + u(rng);
  const PipelineResult r = run_pipeline(hf, "tiny_relief");
  EXPECT_GT(r.pm.max_error(), 0.0);
  EXPECT_LE(r.pm.max_error(), 1e-3 + 1e-9);
}

// ------------------------------------------------------------------------------------------
// Grid sizes

TEST(StressSizes, SmallestAndThinGrids) {
  for (const auto& [W, H] :
       std::vector<std::pair<int, int>>{{2, 2}, {2, 3}, {3, 2}, {2, 17}, {17, 2}, {3, 3}}) {
    const std::string label = "thin_" + std::to_string(W) + "x" + std::to_string(H);
    pm::Heightfield hf = make(
        W, H, [](int c, int r) { return double((c * 7 + r * 13) % 5) * 3.5; }, label);
    run_pipeline(hf, label);
  }
  // The 2 x 2 saddle: no vertex can collapse (all are corners).
  const PipelineResult r =
      run_pipeline(make(
                       2, 2, [](int c, int r) { return (c + r) % 2 ? 100.0 : 0.0; }, "saddle"),
                   "saddle_2x2");
  EXPECT_EQ(r.pm.vsplit_count(), 0u);
  EXPECT_EQ(r.meshes.back().second.triangles.size(), 2u);
}

TEST(StressSizes, PrimeSizes) {
  for (const auto& [W, H] :
       std::vector<std::pair<int, int>>{{127, 131}, {257, 3}, {3, 257}, {2, 257}, {257, 2}}) {
    const std::string label = "prime_" + std::to_string(W) + "x" + std::to_string(H);
    run_pipeline(fractal(W, H, 31), label);
  }
}

TEST(StressSizes, GridsNarrowerThanTwoSamplesAreAClearError) {
  for (const auto& [W, H] : std::vector<std::pair<int, int>>{{1, 50}, {50, 1}, {1, 1}, {1, 2}, {2, 1}}) {
    pm::Heightfield hf(W, H);
    hf.source = "thin.asc";
    try {
      (void)pm::ProgressiveMesh::build(hf);
      ADD_FAILURE() << W << " x " << H << " built";
    } catch (const std::invalid_argument& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("grid is " + std::to_string(W) + " x " + std::to_string(H)), std::string::npos)
          << what;
      EXPECT_NE(what.find("at least 2 x 2"), std::string::npos) << what;
    }
  }
  EXPECT_THROW((void)pm::ProgressiveMesh::build(pm::Heightfield()), std::invalid_argument);
}

// ------------------------------------------------------------------------------------------
// Non-finite samples

TEST(StressNonFinite, BuilderRejectsNaNAndInfNamingTheSampleAndSource) {
  struct Case {
    const char* name;
    std::vector<std::size_t> at;  // sample indices to poison
    double value;
  };
  const int W = 9, H = 7;
  std::vector<std::size_t> row, all;
  for (int c = 0; c < W; ++c) row.push_back(std::size_t(3 * W + c));
  for (std::size_t i = 0; i < std::size_t(W * H); ++i) all.push_back(i);
  const std::vector<Case> cases = {
      {"one NaN", {31}, kNaN}, {"one +inf", {0}, kInf}, {"one -inf", {62}, -kInf},
      {"NaN row", row, kNaN},  {"inf row", row, kInf},  {"all NaN", all, kNaN},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    pm::Heightfield hf(W, H);
    hf.source = "poisoned.tif";
    for (std::size_t i : c.at) hf[i] = c.value;
    try {
      (void)pm::ProgressiveMesh::build(hf);
      ADD_FAILURE() << "built a PM over a non-finite sample";
    } catch (const std::invalid_argument& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("sample " + std::to_string(c.at.front())), std::string::npos) << what;
      EXPECT_NE(what.find("poisoned.tif"), std::string::npos) << what;
      EXPECT_NE(what.find("not finite"), std::string::npos) << what;
    }
  }
}

TEST(StressNonFinite, MaskedSamplesAreHoles) {
  // Voids kept as holes (mask 0, height 0 as the Heightfield contract says): alone, a row that
  // cuts the grid in two, a column, and everywhere but a 3 x 3 island.
  const int W = 25, H = 19;
  struct Case {
    const char* name;
    bool (*hole)(int, int);
  };
  const std::vector<Case> cases = {
      {"holes_single", [](int c, int r) { return c == 12 && r == 9; }},
      {"holes_row", [](int, int r) { return r == 9; }},
      {"holes_column", [](int c, int) { return c == 0 || c == 13; }},
      {"holes_rows_and_columns", [](int c, int r) { return r % 6 == 3 || c % 8 == 5; }},
      {"holes_all_but_island", [](int c, int r) { return !(c >= 10 && c < 13 && r >= 8 && r < 11); }},
  };
  pm::Heightfield base = fractal(W, H, 5, 80.0);
  for (const Case& k : cases) {
    pm::Heightfield hf = base;
    std::vector<std::uint8_t> mask(hf.size(), 1);
    for (int r = 0; r < H; ++r)
      for (int c = 0; c < W; ++c)
        if (k.hole(c, r)) mask[std::size_t(r) * W + c] = 0, hf.at(c, r) = 0.0;
    hf.set_mask(mask);
    const PipelineResult res = run_pipeline(hf, k.name);
    EXPECT_LT(res.pm.full_vertex_count(), hf.size()) << k.name;
  }
}

TEST(StressNonFinite, MaskedNonFiniteSamplesAreIgnored) {
  // A void left as NaN/inf under a mask is not terrain: the builder must not read it.
  pm::Heightfield hf = fractal(17, 13, 8, 40.0);
  std::vector<std::uint8_t> mask(hf.size(), 1);
  for (const auto& [i, v] :
       std::vector<std::pair<std::size_t, double>>{{40, kNaN}, {41, kInf}, {100, -kInf}}) {
    mask[i] = 0;
    hf[i] = v;
  }
  hf.set_mask(mask);
  const PipelineResult r = run_pipeline(hf, "masked_nonfinite");
  EXPECT_EQ(r.pm.full_vertex_count(), hf.size() - 3);
}

TEST(StressNonFinite, NoFaceLeftIsAnEmptyMeshOrAClearError) {
  // Checkerboard voids: every full-resolution face has a void corner, so no face is left.
  pm::Heightfield hf = fractal(12, 10, 3, 50.0);
  std::vector<std::uint8_t> mask(hf.size(), 1);
  for (int r = 0; r < 10; ++r)
    for (int c = 0; c < 12; ++c)
      if ((c + r) % 2) mask[std::size_t(r) * 12 + c] = 0, hf.at(c, r) = 0.0;
  hf.set_mask(mask);
  try {
    const pm::ProgressiveMesh p = pm::ProgressiveMesh::build(hf);
    EXPECT_EQ(p.full_vertex_count(), 0u);
    EXPECT_EQ(p.extract(0.0).triangles.size(), 0u);
    EXPECT_EQ(p.extract(1e300).triangles.size(), 0u);
    EXPECT_TRUE(pm::decode_pm(pm::encode_pm(p), "empty.pm") == p);
    std::printf("  checkerboard voids: an empty PM\n");
  } catch (const std::invalid_argument& e) {
    std::printf("  checkerboard voids: %s\n", e.what());
    EXPECT_NE(std::string(e.what()).find("progressive mesh"), std::string::npos) << e.what();
  }
}

// Voids through read_dem: NODATA or nan/inf tokens in an Esri ASCII grid, NaN and +-inf in a
// float GeoTIFF,
// alone, in rows and columns, and everywhere. Filled, they must give finite heights and a
// sound pipeline; kept, they become holes; all void is a DemError.

/// Writes a W x H float32 GeoTIFF (UTM 33N, 10 m) of `z` through GDAL.
void write_float_tiff(const fs::path& path, int W, int H, const std::vector<double>& z) {
  GDALAllRegister();
  GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("GTiff");
  ASSERT_NE(drv, nullptr);
  GDALDatasetUniquePtr ds(drv->Create(path.c_str(), W, H, 1, GDT_Float32, nullptr));
  ASSERT_TRUE(ds);
  double gt[6] = {500000.0, 10.0, 0.0, 5000000.0 + 10.0 * H, 0.0, -10.0};
  ASSERT_EQ(ds->SetGeoTransform(gt), CE_None);
  std::vector<double> copy = z;
  ASSERT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, W, H, copy.data(), W, H, GDT_Float64, 0, 0),
            CE_None);
}

/// An Esri ASCII grid (UTM-sized corner, 1 cm cells); non-finite values become NODATA, or with
/// `literal` are written as the tokens nan, inf, -inf.
void write_asc(const fs::path& path, int W, int H, const std::vector<double>& z, bool literal) {
  std::ofstream out(path);
  out.precision(17);
  out << "ncols " << W << "\nnrows " << H << "\nxllcorner 500000\nyllcorner 5000000\ncellsize 0.01\n"
      << (literal ? "" : "NODATA_value -9999\n");
  for (int r = 0; r < H; ++r)
    for (int c = 0; c < W; ++c) {
      const double v = z[std::size_t(r) * W + c];
      out << (std::isfinite(v) || literal ? v : -9999.0) << (c + 1 < W ? ' ' : '\n');
    }
  ASSERT_TRUE(out.good());
}

TEST(StressVoids, NaNInfAndNodataThroughReadDem) {
  const int W = 23, H = 17;
  const pm::Heightfield base = fractal(W, H, 12, 90.0);
  struct Pattern {
    const char* name;
    double value;  // the void marker written at the pattern's samples
    bool (*is_void)(int, int);
  };
  const std::vector<Pattern> patterns = {
      {"nan_single", kNaN, [](int c, int r) { return c == 11 && r == 8; }},
      {"inf_single_corner", kInf, [](int c, int r) { return c == 0 && r == 0; }},
      {"neginf_row", -kInf, [](int, int r) { return r == 5; }},
      {"nan_column_border", kNaN, [](int c, int) { return c == 22; }},
      {"nan_rows_and_columns", kNaN, [](int c, int r) { return r % 4 == 1 || c % 6 == 2; }},
      {"nan_all_but_two", kNaN, [](int c, int r) { return !((c == 3 && r == 3) || (c == 19 && r == 12)); }},
      {"nan_everywhere", kNaN, [](int, int) { return true; }},
  };
  const fs::path dir = tmp_file("voids");
  fs::create_directories(dir);
  for (const Pattern& pt : patterns) {
    std::vector<double> z = base.samples();
    std::size_t voids = 0;
    for (int r = 0; r < H; ++r)
      for (int c = 0; c < W; ++c)
        if (pt.is_void(c, r)) z[std::size_t(r) * W + c] = pt.value, ++voids;
    // NODATA in an ASCII grid for every pattern; the non-finite value itself in the GeoTIFF.
    const fs::path tif = dir / (std::string(pt.name) + ".tif"), asc = dir / (std::string(pt.name) + ".asc"),
                   literal = dir / (std::string(pt.name) + "_literal.asc");
    write_float_tiff(tif, W, H, z);
    write_asc(asc, W, H, z, /*literal=*/false);
    write_asc(literal, W, H, z, /*literal=*/true);
    for (const fs::path& file : {tif, asc, literal}) {
      for (const bool fill : {true, false}) {
        const std::string label = file.filename().string() + (fill ? "_filled" : "_holes");
        SCOPED_TRACE(label);
        tb::DemOptions o;
        o.fill_voids = fill;
        if (voids == z.size()) {
          try {
            (void)tb::read_dem(file.string(), o);
            ADD_FAILURE() << "an all-void grid was read";
          } catch (const tb::DemError& e) {
            EXPECT_NE(std::string(e.what()).find("no valid sample"), std::string::npos) << e.what();
            EXPECT_EQ(e.path(), file.string());
          }
          continue;
        }
        const pm::Heightfield hf = tb::read_dem(file.string(), o);
        ASSERT_EQ(hf.voids.voids, voids);
        for (double v : hf.samples()) ASSERT_TRUE(std::isfinite(v));
        if (fill) {
          EXPECT_FALSE(hf.has_holes());
        } else {
          EXPECT_TRUE(hf.has_holes());
        }
        const PipelineResult r = run_pipeline(hf, label);
        if (!fill) {
          EXPECT_LE(r.pm.full_vertex_count(), hf.size() - voids);
        }
      }
    }
  }
}

// ------------------------------------------------------------------------------------------
// Parallel strips on a hostile terrain (the strip path needs >= 65536 samples and >= 256
// columns): cliffs and flat plateaus crossing the strip cut.

TEST(StressParallel, StripBuildOnCliffsAndPlateaus) {
  pm::Heightfield hf = make(
      300, 230,
      [](int c, int r) {
        if (c > 140 && c < 160) return 700.0;  // plateau straddling the cut
        if (r < 40) return 0.0;                // flat band
        return ((c / 30 + r / 25) % 2) * 400.0 + (c % 7);
      },
      "cliffs and plateaus");
  hf.transform = pm::GridTransform::north_up(500000.0, 5000000.0, 0.01, 0.01);
  PipelineOptions o;
  o.threads = 2;
  const PipelineResult a = run_pipeline(hf, "strips_cliffs", o);
  const pm::ProgressiveMesh b = pm::ProgressiveMesh::build(hf, tt::build_threads(2));
  EXPECT_TRUE(a.pm == b) << "the strip build is not deterministic";
}

}  // namespace
