// Tests of ProgressiveMesh::build/extract and LInfError, checked by the independent mesh checker.
//
// Every mesh the PM hands out is measured against the full-resolution samples by
// tests/support/mesh_checker (which shares no code with LInfError or the builder): its error
// must be within the bound extract() reports and within the requested E, it must cover the
// domain exactly once, and it must be watertight. Hand-drawn fixtures pin the numbers.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <map>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "mesh_checker.hpp"
#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/linf_error.hpp"
#include "terralod/pm/openmesh_build.hpp"
#include "terralod/pm/progressive_mesh.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace {

namespace pm = terralod::pm;
using terralod::test::check_mesh;
using terralod::test::CheckOptions;
using terralod::test::MeshCheck;

const std::vector<double> kErrors = {0.0, 0.5, 1.0, 2.0, 5.0, 20.0, 100.0};

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

/// ProgressiveMesh::build(hf, options), printing "  <what>: build <ms> ms".
pm::ProgressiveMesh timed_build(const pm::Heightfield& hf, const std::string& what,
                                const pm::BuildOptions& options = {}) {
  const auto t0 = std::chrono::steady_clock::now();
  pm::ProgressiveMesh p = pm::ProgressiveMesh::build(hf, options);
  std::printf("  %s: build %.0f ms\n", what.c_str(), ms_since(t0));
  return p;
}

// A W x H heightfield from rows listed north (row 0) first.
pm::Heightfield grid(int W, int H, const std::vector<double>& z) {
  pm::Heightfield hf(W, H);
  hf.samples() = z;
  return hf;
}

std::uint32_t idx(const pm::Heightfield& hf, int col, int row) {
  return std::uint32_t(row * hf.width() + col);
}

// The full-resolution mesh, written independently of ProgressiveMesh: every grid face whose
// corners are valid, cell (i,j) split along (i,j)-(i+1,j+1).
pm::TriangleMesh grid_mesh(const pm::Heightfield& hf) {
  pm::TriangleMesh m;
  std::vector<std::uint32_t> index(hf.size(), UINT32_MAX);
  auto vertex = [&](int c, int r) {
    const std::uint32_t s = idx(hf, c, r);
    if (index[s] == UINT32_MAX) index[s] = std::uint32_t(m.vertices.size()), m.vertices.push_back(s);
    return index[s];
  };
  for (int j = 0; j + 1 < hf.height(); ++j)
    for (int i = 0; i + 1 < hf.width(); ++i) {
      if (hf.valid(i, j) && hf.valid(i + 1, j) && hf.valid(i + 1, j + 1))
        m.triangles.push_back({vertex(i, j), vertex(i + 1, j), vertex(i + 1, j + 1)});
      if (hf.valid(i, j) && hf.valid(i + 1, j + 1) && hf.valid(i, j + 1))
        m.triangles.push_back({vertex(i, j), vertex(i + 1, j + 1), vertex(i, j + 1)});
    }
  return m;
}

// A mesh from triangles given as (col,row) corner triples.
pm::TriangleMesh mesh_of(const pm::Heightfield& hf,
                         const std::vector<std::array<std::array<int, 2>, 3>>& tris) {
  pm::TriangleMesh m;
  std::vector<std::uint32_t> index(hf.size(), UINT32_MAX);
  for (const auto& t : tris) {
    std::array<std::uint32_t, 3> out;
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t s = idx(hf, t[k][0], t[k][1]);
      if (index[s] == UINT32_MAX) index[s] = std::uint32_t(m.vertices.size()), m.vertices.push_back(s);
      out[k] = index[s];
    }
    m.triangles.push_back(out);
  }
  return m;
}

// The (col,row) corners of every triangle of a mesh, the inverse of mesh_of.
std::vector<std::array<std::array<int, 2>, 3>> corners_of(const pm::Heightfield& hf,
                                                          const pm::TriangleMesh& m) {
  std::vector<std::array<std::array<int, 2>, 3>> out;
  for (const auto& t : m.triangles) {
    std::array<std::array<int, 2>, 3> x;
    for (int k = 0; k < 3; ++k)
      x[k] = {int(m.vertices[t[k]] % hf.width()), int(m.vertices[t[k]] / hf.width())};
    out.push_back(x);
  }
  return out;
}

bool has_vertex(const pm::TriangleMesh& m, std::uint32_t sample) {
  return std::find(m.vertices.begin(), m.vertices.end(), sample) != m.vertices.end();
}

// ------------------------------------------------------------------------------------------
// Every mesh of the sequence, not only the few E of kErrors: the collapses are followed face
// by face (independently of extract) and every triangle a collapse creates is measured with
// the checker's kernel. Each mesh extract_after(k) is made of triangles created by collapses
// 0..k-1 (or full-resolution faces, error 0), so if each new triangle is within the largest
// error of the collapses up to its own, every mesh of the PM is within its reported bound.

void verify_every_collapse(const pm::Heightfield& hf, const pm::ProgressiveMesh& p,
                           const std::string& label) {
  SCOPED_TRACE(label + ": every collapse");
  const bool continuous = p.metric() == pm::ErrorMetric::Continuous;
  bool integers = true;
  double zmax = 0.0;
  for (std::size_t s = 0; s < hf.size(); ++s)
    if (hf.valid(s)) {
      integers = integers && hf[s] == std::floor(hf[s]);
      zmax = std::max(zmax, std::abs(hf[s]));
    }
  const double tol = integers ? 0.0 : 1e-12 * std::max(1.0, zmax);
  const int W = hf.width();
  auto at = [&](std::uint32_t s) {
    std::string out(1, '(');  // appended piecewise: GCC 12 warns falsely (-Wrestrict) on "(" + string
    out += std::to_string(s % W);
    out += ',';
    out += std::to_string(s / W);
    return out += ')';
  };

  std::vector<std::array<std::uint32_t, 3>> faces;
  std::vector<std::uint8_t> alive;
  std::vector<std::vector<std::uint32_t>> around(hf.size());
  auto add = [&](const std::array<std::uint32_t, 3>& f) {
    for (std::uint32_t v : f) around[v].push_back(std::uint32_t(faces.size()));
    faces.push_back(f), alive.push_back(1);
  };
  const pm::TriangleMesh full = p.extract_after(0);
  for (const auto& t : full.triangles) add({full.vertices[t[0]], full.vertices[t[1]], full.vertices[t[2]]});

  const auto t0 = std::chrono::steady_clock::now();
  std::unordered_map<std::uint64_t, double> edge_cache;
  double prefix = 0.0;
  std::size_t violations = 0, flips = 0, measured = 0;
  for (std::size_t k = 0; k < p.collapses().size(); ++k) {
    const pm::Collapse c = p.collapses()[k];
    prefix = std::max(prefix, c.error);
    std::vector<std::uint32_t> ring;
    ring.swap(around[c.u]);
    for (std::uint32_t id : ring) {
      if (!alive[id]) continue;
      alive[id] = 0;
      std::array<std::uint32_t, 3> f = faces[id];
      if (f[0] == c.w || f[1] == c.w || f[2] == c.w) continue;  // the faces beside the edge vanish
      for (auto& v : f)
        if (v == c.u) v = c.w;
      add(f);
      const auto P = [&](std::uint32_t s) { return std::array<std::int64_t, 2>{s % W, s / W}; };
      const auto a = P(f[0]), b = P(f[1]), d = P(f[2]);
      if ((b[0] - a[0]) * (d[1] - a[1]) - (b[1] - a[1]) * (d[0] - a[0]) <= 0 && flips++ == 0)
        ADD_FAILURE() << "collapse " << k << " " << at(c.u) << " -> " << at(c.w) << " flips triangle "
                      << at(f[0]) << at(f[1]) << at(f[2]);
      // Samples inside the new triangle, and crossings along its edges; a long edge's error is
      // cached because a fan of new triangles shares its edges.
      const double samples =
          terralod::test::triangle_error(hf, f[0], f[1], f[2], /*continuous=*/false).samples;
      double crossings = 0.0;
      if (continuous)
        for (int e = 0; e < 3; ++e) {
          const std::uint32_t s0 = std::min(f[e], f[(e + 1) % 3]), s1 = std::max(f[e], f[(e + 1) % 3]);
          const auto p0 = P(s0), p1 = P(s1);
          if (std::abs(p1[0] - p0[0]) + std::abs(p1[1] - p0[1]) < 16) {  // short: cheaper to measure
            crossings = std::max(crossings, terralod::test::edge_error(hf, s0, s1));
            continue;
          }
          const auto [it, fresh] = edge_cache.try_emplace(std::uint64_t(s0) << 32 | s1, 0.0);
          if (fresh) it->second = terralod::test::edge_error(hf, s0, s1);
          crossings = std::max(crossings, it->second);
        }
      ++measured;
      const double err = std::max(samples, crossings);
      if (err > prefix + tol && violations++ == 0)
        ADD_FAILURE() << "collapse " << k << " " << at(c.u) << " -> " << at(c.w) << " recorded error "
                      << c.error << " (largest so far " << prefix << ") creates triangle " << at(f[0])
                      << at(f[1]) << at(f[2]) << " whose error is " << err << " (samples " << samples
                      << ", crossings " << crossings << ")";
    }
  }
  EXPECT_EQ(violations, 0u) << "collapses creating a triangle beyond the bound";
  EXPECT_EQ(flips, 0u);
  std::printf("  %-34s followed %zu collapses, measured %zu new triangles, %zu beyond the bound (%.0f ms)\n",
              label.c_str(), p.collapses().size(), measured, violations, ms_since(t0));
}

// ------------------------------------------------------------------------------------------
// The property check applied to every PM: collapse invariants, then every E of kErrors.

struct Verified {
  std::vector<std::size_t> triangles;  // per E of kErrors
  std::size_t base_triangles = 0;
};

Verified verify_pm(const pm::Heightfield& hf, const pm::ProgressiveMesh& p, const std::string& label) {
  SCOPED_TRACE(label);
  Verified out;
  const int W = hf.width(), H = hf.height();
  const bool continuous = p.metric() == pm::ErrorMetric::Continuous;
  const auto& cs = p.collapses();
  const double q = p.error_quantum();
  EXPECT_GT(q, 0.0);
  EXPECT_EQ(q, std::ldexp(1.0, std::ilogb(q))) << "quantum " << q << " is not a power of two";

  // Collapse invariants: corners never collapse; a border vertex stays on its border line;
  // errors are non-negative multiples of the quantum.
  std::size_t bad_corner = 0, bad_border = 0, bad_quantum = 0;
  for (std::size_t k = 0; k < cs.size(); ++k) {
    const int ux = int(cs[k].u % W), uy = int(cs[k].u / W), wx = int(cs[k].w % W), wy = int(cs[k].w / W);
    const bool corner = (ux == 0 || ux == W - 1) && (uy == 0 || uy == H - 1);
    if (corner && bad_corner++ == 0)
      ADD_FAILURE() << "collapse " << k << " removes corner (" << ux << "," << uy << ")";
    const bool border_ok = (ux != 0 || wx == 0) && (ux != W - 1 || wx == W - 1) && (uy != 0 || wy == 0) &&
                           (uy != H - 1 || wy == H - 1);
    if (!border_ok && bad_border++ == 0)
      ADD_FAILURE() << "collapse " << k << " moves border vertex (" << ux << "," << uy << ") to (" << wx
                    << "," << wy << ")";
    const double m = cs[k].error / q;
    if ((!(cs[k].error >= 0.0) || m != std::floor(m)) && bad_quantum++ == 0)
      ADD_FAILURE() << "collapse " << k << " error " << cs[k].error << " is not a multiple of the quantum "
                    << q;
  }
  EXPECT_EQ(bad_corner, 0u);
  EXPECT_EQ(bad_border, 0u);
  EXPECT_EQ(bad_quantum, 0u);

  CheckOptions opt;
  opt.excluded_faces = p.dropped_faces();
  opt.continuous = true;  // always measured; only required to be within E for Continuous

  // The full-resolution mesh: every domain face, exact heights.
  const pm::TriangleMesh full = p.extract_after(0);
  const MeshCheck c0 = check_mesh(hf, full, opt);
  EXPECT_TRUE(c0.ok(0.0)) << c0.describe();
  EXPECT_EQ(c0.max_sample_error, 0.0);
  EXPECT_EQ(c0.max_crossing_error, 0.0);
  EXPECT_EQ(full.error_bound, 0.0);
  EXPECT_EQ(full.triangles.size(), c0.domain_faces);
  EXPECT_EQ(full.vertices.size(), p.full_vertex_count());
  if (!hf.has_holes()) {
    EXPECT_EQ(full.triangles.size(), 2 * std::size_t(W - 1) * std::size_t(H - 1));
    EXPECT_TRUE(p.dropped_faces().empty());
  }

  std::size_t previous = full.triangles.size();
  for (double E : kErrors) {
    SCOPED_TRACE("E = " + std::to_string(E));
    const auto t0 = std::chrono::steady_clock::now();
    const pm::TriangleMesh m = p.extract(E);
    const double extract_ms = ms_since(t0);
    // The prefix extract(E) performs is the longest one whose largest error is <= E, and the
    // bound it reports is that largest error (recomputed here from the collapse list).
    const std::size_t n = p.collapses_within(E);
    double prefix = 0.0;
    for (std::size_t k = 0; k < n; ++k) prefix = std::max(prefix, cs[k].error);
    EXPECT_LE(prefix, E);
    if (n < cs.size()) {
      EXPECT_GT(std::max(prefix, cs[n].error), E) << "extract stopped early at collapse " << n;
    }
    EXPECT_EQ(m.error_bound, prefix);
    EXPECT_LE(m.error_bound, E);
    EXPECT_EQ(m.vertices.size(), p.full_vertex_count() - n);
    EXPECT_LE(m.triangles.size(), previous) << "triangle count grew with E";
    previous = m.triangles.size();
    out.triangles.push_back(m.triangles.size());

    const auto t1 = std::chrono::steady_clock::now();
    const MeshCheck c = check_mesh(hf, m, opt);
    const double check_ms = ms_since(t1);
    EXPECT_TRUE(c.topology_ok()) << c.describe();
    EXPECT_TRUE(c.ok(E, continuous)) << c.describe();
    EXPECT_TRUE(c.ok(m.error_bound, continuous))
        << "error exceeds the reported bound " << m.error_bound << "\n"
        << c.describe();
    if (E == 0.0) {
      EXPECT_EQ(c.max_sample_error, 0.0) << c.describe();
    }
    std::printf(
        "  %-34s E=%6.1f: %8zu tris, bound %9.4f, sample err %9.4f, continuous err %9.4f (extract %.0f ms, "
        "check %.0f ms)\n",
        label.c_str(), E, m.triangles.size(), m.error_bound, c.max_sample_error, c.max_continuous_error(),
        extract_ms, check_ms);
  }

  verify_every_collapse(hf, p, label);

  // The base mesh: within the PM's largest error; for a hole-free grid only corners should be
  // left (2 triangles) unless collapses get stuck.
  const pm::TriangleMesh base = p.extract_after(cs.size());
  const MeshCheck cb = check_mesh(hf, base, opt);
  EXPECT_TRUE(cb.ok(p.max_error(), continuous)) << cb.describe();
  EXPECT_EQ(base.error_bound, p.max_error());
  EXPECT_EQ(base.vertices.size(), p.base_vertex_count());
  out.base_triangles = base.triangles.size();
  std::printf(
      "  %-34s base mesh: %zu vertices, %zu triangles, max error %.4f, %zu collapses, %zu dropped faces\n",
      label.c_str(), base.vertices.size(), base.triangles.size(), p.max_error(), cs.size(),
      p.dropped_faces().size());
  if (!hf.has_holes()) {
    for (auto [c, r] : {std::pair{0, 0}, {W - 1, 0}, {0, H - 1}, {W - 1, H - 1}})
      EXPECT_TRUE(has_vertex(base, idx(hf, c, r)))
          << "corner (" << c << "," << r << ") missing from the base mesh";
    EXPECT_LE(base.triangles.size(), 8u)
        << "collapses got stuck: the base mesh keeps " << base.vertices.size() << " vertices";
  }
  return out;
}

// ------------------------------------------------------------------------------------------
// Real SRTM tiles (skipped when ../shared/data is absent).

constexpr int kHgt = 1201;
constexpr std::int16_t kVoid = -32768;

// The raw samples of a 1201 x 1201 .hgt tile (big-endian int16, row 0 north), or nothing.
std::optional<std::vector<std::int16_t>> read_hgt(const std::string& name) {
  const std::string path = std::string(TERRALOD_DATA_DIR) + "/" + name;
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  std::vector<unsigned char> bytes(std::size_t(kHgt) * kHgt * 2);
  in.read(reinterpret_cast<char*>(bytes.data()), std::streamsize(bytes.size()));
  if (in.gcount() != std::streamsize(bytes.size())) {
    ADD_FAILURE() << path << " is shorter than a 1201 x 1201 SRTM3 tile";
    return std::nullopt;
  }
  std::vector<std::int16_t> z(std::size_t(kHgt) * kHgt);
  for (std::size_t i = 0; i < z.size(); ++i)
    z[i] = std::int16_t(std::uint16_t(bytes[2 * i] << 8 | bytes[2 * i + 1]));
  return z;
}

enum class Voids { Fill, Holes };

// A crop of a tile. Voids are filled with the mean of their valid 4-neighbours, sweep after
// sweep (each sweep fills the voids that touch filled samples), or kept as holes in the mask.
pm::Heightfield crop(const std::vector<std::int16_t>& raw, int c0, int r0, int w, int h, Voids voids,
                     std::size_t* void_count = nullptr) {
  pm::Heightfield hf(w, h);
  std::vector<std::uint8_t> ok(hf.size(), 1);
  std::size_t count = 0;
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) {
      const std::int16_t v = raw[std::size_t(r0 + r) * kHgt + (c0 + c)];
      if (v == kVoid)
        ok[std::size_t(r) * w + c] = 0, ++count;
      else
        hf.at(c, r) = v;
    }
  if (void_count) *void_count = count;
  if (count == 0) return hf;
  if (voids == Voids::Holes) {
    hf.set_mask(ok);
    return hf;
  }
  for (bool progress = true; progress;) {
    progress = false;
    std::vector<std::uint8_t> next = ok;
    for (int r = 0; r < h; ++r)
      for (int c = 0; c < w; ++c) {
        if (ok[std::size_t(r) * w + c]) continue;
        double sum = 0;
        int n = 0;
        for (auto [dc, dr] : {std::pair{1, 0}, {-1, 0}, {0, 1}, {0, -1}}) {
          const int cc = c + dc, rr = r + dr;
          if (cc < 0 || rr < 0 || cc >= w || rr >= h || !ok[std::size_t(rr) * w + cc]) continue;
          sum += hf.at(cc, rr), ++n;
        }
        if (n) hf.at(c, r) = std::round(sum / n), next[std::size_t(r) * w + c] = 1, progress = true;
      }
    ok.swap(next);
  }
  return hf;
}

// ------------------------------------------------------------------------------------------
// The checker itself: it must see what it claims to see.

// 3 x 3 zeros: the full grid is exact and watertight.
TEST(MeshChecker, AcceptsTheFullResolutionGrid) {
  const pm::Heightfield hf = grid(3, 3, std::vector<double>(9, 0.0));
  const MeshCheck c = check_mesh(hf, grid_mesh(hf));
  EXPECT_TRUE(c.ok(0.0)) << c.describe();
  EXPECT_EQ(c.triangles, 8u);
  EXPECT_EQ(c.domain_faces, 8u);
  EXPECT_EQ(c.edges, 16u);  // 12 axis edges + 4 diagonals
  EXPECT_EQ(c.boundary_edges, 8u);
  EXPECT_EQ(c.area2_sum, 8);
}

// Grid 4 x 2, a ridge between samples (heights in metres; row 0 first):
//
//   row 0:  0  12   6   0          mesh:  (0,1)-----------(3,1)
//   row 1:  0   0   0   3                   |  T1    ___/ / |
//                                           |  ___/   T2 / T3|
//                                         (0,0)---(1,0)-----(3,0)
//
// T1 = (0,0),(3,1),(0,1): its plane is z = x. Samples inside: row 1, errors |1-0| = 1 at
// (1,1) and |2-0| = 2 at (2,1). T2 = (0,0),(1,0),(3,1) and T3 = (1,0),(3,0),(3,1) contain only
// their corners and (2,0): T3's plane z = 12 - 6(x-1) + 3y gives 6 at (2,0), exact. So the
// sample error is 2 at (2,1).
// Crossings of the edge (0,0)-(3,1) (heights 0 -> 3): at x = 1 (t = 1/3, y = 1/3) the edge is
// at 1; the full surface there is on the vertical grid edge (1,0)-(1,1): 12 + (1/3)(0 - 12) = 8,
// error 7. At x = 2 (y = 2/3): edge 2, surface 6 + (2/3)(0 - 6) = 2, error 0. At the diagonal
// x - y = 1 (t = 1/2, point (1.5, 0.5)): edge 1.5, surface (z(1,0) + z(2,1))/2 = 6, error 4.5.
// Edge (1,0)-(3,1) (12 -> 3) at x = 2, y = 1/2: edge 7.5, surface (6 + 0)/2 = 3, error 4.5.
// Edge (0,1)-(3,1) meets samples (1,1), (2,1): errors 1, 2. So the continuous error is 7 at (1, 1/3).
TEST(MeshChecker, RidgeBetweenSamplesByHand) {
  const pm::Heightfield hf = grid(4, 2, {0, 12, 6, 0, 0, 0, 0, 3});
  const pm::TriangleMesh m =
      mesh_of(hf, {{{{0, 0}, {3, 1}, {0, 1}}}, {{{0, 0}, {1, 0}, {3, 1}}}, {{{1, 0}, {3, 0}, {3, 1}}}});
  const MeshCheck c = check_mesh(hf, m);
  EXPECT_TRUE(c.topology_ok()) << c.describe();
  EXPECT_EQ(c.max_sample_error, 2.0);
  EXPECT_EQ(c.worst_sample_col, 2);
  EXPECT_EQ(c.worst_sample_row, 1);
  EXPECT_DOUBLE_EQ(c.max_crossing_error, 7.0);
  EXPECT_DOUBLE_EQ(c.worst_crossing_col, 1.0);
  EXPECT_DOUBLE_EQ(c.worst_crossing_row, 1.0 / 3.0);
  EXPECT_TRUE(c.ok(2.0, /*continuous=*/false));
  EXPECT_FALSE(c.ok(6.9));
  EXPECT_TRUE(c.ok(7.0 + 1e-12));
}

TEST(MeshChecker, DetectsFlipGapOverlapAndCrack) {
  const pm::Heightfield hf = grid(3, 3, std::vector<double>(9, 0.0));
  {  // One triangle turned clockwise.
    pm::TriangleMesh m = grid_mesh(hf);
    std::swap(m.triangles[3][1], m.triangles[3][2]);
    const MeshCheck c = check_mesh(hf, m);
    EXPECT_EQ(c.flipped, 1u);
    EXPECT_FALSE(c.ok(0.0));
  }
  {  // One triangle missing: a gap whose three edges are open inside the domain.
    pm::TriangleMesh m = grid_mesh(hf);
    m.triangles.erase(m.triangles.begin() + 3);
    const MeshCheck c = check_mesh(hf, m);
    EXPECT_EQ(c.uncovered_faces, 1u);
    EXPECT_EQ(c.area2_sum, 7);
    EXPECT_GE(c.open_edges_off_boundary, 2u);
    EXPECT_FALSE(c.ok(0.0));
  }
  {  // A coarse triangle laid over the fine ones: overlaps, and its diagonal (0,0)-(2,2) is open
     // inside the domain (its other edges lie on the border).
    auto tris = corners_of(hf, grid_mesh(hf));
    tris.push_back({{{0, 0}, {2, 0}, {2, 2}}});
    const MeshCheck c = check_mesh(hf, mesh_of(hf, tris));
    EXPECT_EQ(c.overlapped_faces, 4u);
    EXPECT_EQ(c.area2_sum, 8 + 4);
    EXPECT_EQ(c.open_edges_off_boundary, 1u);
    EXPECT_FALSE(c.topology_ok());
  }
  {  // A T-junction: left column fine, right column one coarse quad. Area and coverage are
     // exact, but the edge (1,0)-(1,2) meets (1,0)-(1,1) and (1,1)-(1,2): three open edges.
    const pm::TriangleMesh m = mesh_of(hf, {{{{0, 0}, {1, 0}, {1, 1}}},
                                            {{{0, 0}, {1, 1}, {0, 1}}},
                                            {{{0, 1}, {1, 1}, {1, 2}}},
                                            {{{0, 1}, {1, 2}, {0, 2}}},
                                            {{{1, 0}, {2, 0}, {2, 2}}},
                                            {{{1, 0}, {2, 2}, {1, 2}}}});
    const MeshCheck c = check_mesh(hf, m);
    EXPECT_EQ(c.area2_sum, 8);
    EXPECT_EQ(c.uncovered_faces + c.overlapped_faces, 0u);
    EXPECT_EQ(c.open_edges_off_boundary, 3u);
    EXPECT_FALSE(c.ok(0.0));
  }
  {  // Vertices that are not samples, and a triangle index out of range.
    pm::TriangleMesh m = grid_mesh(hf);
    m.vertices[0] = 99;
    m.triangles.push_back({0, 1, 77});
    const MeshCheck c = check_mesh(hf, m);
    EXPECT_EQ(c.bad_vertices, 1u);
    EXPECT_EQ(c.bad_indices, 1u);
    EXPECT_FALSE(c.ok(0.0));
  }
}

// 5 x 5 with a hole at sample (2,2): its 6 faces leave the domain, whose boundary is the 16 unit
// edges of the border plus the hexagon (1,1),(2,1),(3,2),(3,3),(2,3),(1,2) around the hole.
TEST(MeshChecker, HolesAreOutsideTheDomain) {
  pm::Heightfield hf = grid(5, 5, std::vector<double>(25, 1.0));
  std::vector<std::uint8_t> mask(25, 1);
  mask[2 * 5 + 2] = 0;
  hf.set_mask(mask);
  const pm::TriangleMesh m = grid_mesh(hf);
  const MeshCheck c = check_mesh(hf, m);
  EXPECT_TRUE(c.ok(0.0)) << c.describe();
  EXPECT_EQ(c.domain_faces, 32u - 6u);
  EXPECT_EQ(c.boundary_edges, 16u + 6u);

  // Bridging the hole with a fan from (1,1) covers faces outside the domain.
  auto tris = corners_of(hf, m);
  tris.push_back({{{1, 1}, {2, 1}, {3, 2}}});
  tris.push_back({{{1, 1}, {3, 2}, {3, 3}}});
  tris.push_back({{{1, 1}, {3, 3}, {2, 3}}});
  tris.push_back({{{1, 1}, {2, 3}, {1, 2}}});
  const MeshCheck b = check_mesh(hf, mesh_of(hf, tris));
  EXPECT_EQ(b.covered_outside, 6u);
  EXPECT_EQ(b.area2_sum, 26 + 6);
  EXPECT_FALSE(b.ok(0.0));
}

// ------------------------------------------------------------------------------------------
// LInfError on hand-computed cases.

// A 5 x 5 plane z = 3x - 2y + 7 is reproduced exactly by every triangle and segment.
TEST(LInfError, PlaneHasZeroErrorForEveryTriangle) {
  pm::Heightfield hf(5, 5);
  for (int r = 0; r < 5; ++r)
    for (int c = 0; c < 5; ++c) hf.at(c, r) = 3.0 * c - 2.0 * r + 7.0;
  const pm::LInfError cont(hf, pm::ErrorMetric::Continuous), samp(hf, pm::ErrorMetric::Samples);
  int measured = 0;
  for (int a = 0; a < 25; ++a)
    for (int b = 0; b < 25; ++b)
      for (int c = 0; c < 25; ++c) {
        const pm::GridPoint A{a % 5, a / 5}, B{b % 5, b / 5}, C{c % 5, c / 5};
        if (pm::orient2d(A, B, C) <= 0) continue;
        ASSERT_EQ(cont.triangle(A, B, C), 0.0);
        ASSERT_EQ(samp.triangle(A, B, C), 0.0);
        ++measured;
      }
  EXPECT_GT(measured, 1000);
  for (int a = 0; a < 25; ++a)
    for (int b = 0; b < 25; ++b)
      if (a != b) {
        ASSERT_EQ(cont.segment({a % 5, a / 5}, {b % 5, b / 5}), 0.0);
      }
}

// 5 x 5 plane z = x + 2y with a spike of +3 at (2,1) (so z(2,1) = 7, the plane gives 4).
// Triangle (0,0),(4,0),(0,4) interpolates the plane, and (2,1) is inside (2 + 1 <= 4): the
// sample error is exactly 3. Its hypotenuse x + y = 4 runs through the spike's star between
// (3,1) and (2,2), crossing the diagonal x - y = 1 at (2.5, 1.5), where the full surface is
// (z(2,1) + z(3,2))/2 = (7 + 7)/2 = 7 against the plane's 2.5 + 3 = 5.5: error 1.5 < 3.
TEST(LInfError, SpikeInsideTriangleGivesItsHeight) {
  pm::Heightfield hf(5, 5);
  for (int r = 0; r < 5; ++r)
    for (int c = 0; c < 5; ++c) hf.at(c, r) = c + 2.0 * r;
  hf.at(2, 1) += 3.0;
  const pm::LInfError cont(hf, pm::ErrorMetric::Continuous), samp(hf, pm::ErrorMetric::Samples);
  EXPECT_EQ(samp.triangle({0, 0}, {4, 0}, {0, 4}), 3.0);
  EXPECT_EQ(cont.triangle({0, 0}, {4, 0}, {0, 4}), 3.0);
  EXPECT_EQ(cont.samples_in_triangle({0, 0}, {4, 0}, {0, 4}), 3.0);
  EXPECT_EQ(cont.segment({4, 0}, {0, 4}), 1.5);
  EXPECT_EQ(cont.segment({0, 4}, {4, 0}), 1.5);
  // A triangle that does not contain (2,1) nor touch its star is exact.
  EXPECT_EQ(cont.triangle({0, 2}, {4, 2}, {4, 4}), 0.0);
  // The independent checker agrees on the mesh made of that triangle and its complement.
  const pm::TriangleMesh m = mesh_of(hf, {{{{0, 0}, {4, 0}, {0, 4}}}, {{{4, 0}, {4, 4}, {0, 4}}}});
  const MeshCheck c = check_mesh(hf, m);
  EXPECT_TRUE(c.topology_ok()) << c.describe();
  EXPECT_EQ(c.max_sample_error, 3.0);
  EXPECT_EQ(c.max_continuous_error(), 3.0);
}

// The ridge of MeshChecker.RidgeBetweenSamplesByHand: the segment (0,0)-(3,1) is off by 7 m at
// (1, 1/3), between the samples (1,0) and (1,1), while every sample on it is exact. The triangle
// (0,0),(3,1),(0,1) has sample error 2 (at (2,1)) but continuous error 7.
TEST(LInfError, SegmentCrossingRidgeBetweenSamples) {
  const pm::Heightfield hf = grid(4, 2, {0, 12, 6, 0, 0, 0, 0, 3});
  const pm::LInfError cont(hf, pm::ErrorMetric::Continuous), samp(hf, pm::ErrorMetric::Samples);
  EXPECT_DOUBLE_EQ(cont.segment({0, 0}, {3, 1}), 7.0);
  EXPECT_DOUBLE_EQ(cont.segment({3, 1}, {0, 0}), 7.0);
  EXPECT_DOUBLE_EQ(cont.segment({1, 0}, {3, 1}), 4.5);
  EXPECT_EQ(cont.samples_in_triangle({0, 0}, {3, 1}, {0, 1}), 2.0);
  EXPECT_EQ(samp.triangle({0, 0}, {3, 1}, {0, 1}), 2.0);
  EXPECT_DOUBLE_EQ(cont.triangle({0, 0}, {3, 1}, {0, 1}), 7.0);
  EXPECT_DOUBLE_EQ(cont.triangle({0, 1}, {0, 0}, {3, 1}), 7.0);  // any rotation
  EXPECT_EQ(cont.surface_height(1.5, 0.5), 6.0);
  EXPECT_EQ(cont.surface_height(1.0, 0.5), 6.0);
  EXPECT_NEAR(cont.surface_height(1.0, 1.0 / 3.0), 8.0, 1e-12);
}

// The cutoff contract of LInfError: "when the error exceeds cutoff, evaluation may stop early
// and return any value > cutoff" -- so a value <= cutoff must be the exact error. Triangle
// (0,0),(4,1),(1,3) has area2 = 4*3 - 1*1 = 11; heights are 0 except z(1,3) = 5, so the plane
// at a sample is 5 w_c / 11 with w_c = orient((0,0),(4,1),p) = 4 p.y - p.x:
//
//   row 0: (0,0) corner
//   row 1: (1,1) w_c = 3 -> 15/11,  (2,1) 10/11,  (3,1) 5/11,  (4,1) corner
//   row 2: (1,2) w_c = 7 -> 35/11,  (2,2) 30/11
//   row 3: (1,3) corner
//
// The exact sample error is 35/11 at (1,2). (The continuous error is 4: the edge (4,1)-(1,3)
// crosses the diagonal x - y = -1 at t = 4/5, (1.6, 2.6), where it is at 4 m and the surface,
// on the grid diagonal (1,2)-(2,3), is 0.) With cutoff = 15/11 (a double), the scan may stop after
// row 1, but it must then return a value > cutoff. In doubles (15/11) * 11 rounds to
// 14.999999999999998 < 15, while 15 / 11 rounds back to the cutoff itself: a scan that
// compares the numerator with cutoff * area stops early and returns exactly the cutoff, which
// its caller cannot tell from an exact error of 15/11.
TEST(LInfError, CutoffNeverHidesALargerError) {
  pm::Heightfield hf(5, 4);
  hf.at(1, 3) = 5.0;
  const pm::GridPoint a{0, 0}, b{4, 1}, c{1, 3};
  ASSERT_EQ(pm::orient2d(a, b, c), 11);
  const double exact = 35.0 / 11.0, cutoff = 15.0 / 11.0;
  ASSERT_LT(cutoff * 11.0, 15.0) << "the rounding this fixture relies on";
  for (auto metric : {pm::ErrorMetric::Samples, pm::ErrorMetric::Continuous}) {
    SCOPED_TRACE(metric == pm::ErrorMetric::Continuous ? "continuous" : "samples");
    const pm::LInfError err(hf, metric);
    const double exact_triangle = metric == pm::ErrorMetric::Continuous ? 4.0 : exact;
    EXPECT_DOUBLE_EQ(err.samples_in_triangle(a, b, c), exact);
    EXPECT_DOUBLE_EQ(err.triangle(a, b, c), exact_triangle);
    const double s = err.samples_in_triangle(a, b, c, cutoff);
    EXPECT_TRUE(s > cutoff || s == exact) << "samples_in_triangle(cutoff = 15/11) returned " << s
                                          << ", neither above the cutoff nor the exact " << exact;
    const double t = err.triangle(a, b, c, cutoff);
    EXPECT_TRUE(t > cutoff || t == exact_triangle)
        << "triangle(cutoff = 15/11) returned " << t << ", neither above the cutoff nor the exact "
        << exact_triangle;
  }
  // The checker's kernel measures the same triangle independently.
  const terralod::test::TriangleError te = terralod::test::triangle_error(hf, 0, 1 * 5 + 4, 3 * 5 + 1);
  EXPECT_DOUBLE_EQ(te.samples, exact);
  EXPECT_DOUBLE_EQ(te.crossings, 4.0);
}

// ------------------------------------------------------------------------------------------
// Hand-drawn PM fixtures.

// 2 x 2: four corners, nothing can collapse.
TEST(ProgressiveMesh, TwoByTwoHasNoCollapses) {
  const pm::Heightfield hf = grid(2, 2, {1, 2, 3, 5});
  const pm::ProgressiveMesh p = pm::ProgressiveMesh::build(hf);
  EXPECT_EQ(p.vsplit_count(), 0u);
  EXPECT_EQ(p.full_vertex_count(), 4u);
  EXPECT_EQ(p.max_error(), 0.0);
  const pm::TriangleMesh m = p.extract(0.0);
  EXPECT_EQ(m.triangles.size(), 2u);
  EXPECT_TRUE(check_mesh(hf, m).ok(0.0));
}

// 3 x 3 plane z = x + 2y (row 0 first):   0 1 2 / 2 3 4 / 4 5 6.
// Any triangle of samples lies on the plane, so every collapse has error 0 and extract(0)
// goes all the way down to the two corner triangles.
TEST(ProgressiveMesh, PlaneCollapsesToTwoTrianglesAtZeroError) {
  const pm::Heightfield hf = grid(3, 3, {0, 1, 2, 2, 3, 4, 4, 5, 6});
  for (auto metric : {pm::ErrorMetric::Continuous, pm::ErrorMetric::Samples}) {
    pm::BuildOptions o;
    o.metric = metric;
    const pm::ProgressiveMesh p = pm::ProgressiveMesh::build(hf, o);
    EXPECT_EQ(p.vsplit_count(), 5u);
    for (const pm::Collapse& c : p.collapses()) EXPECT_EQ(c.error, 0.0);
    const pm::TriangleMesh m = p.extract(0.0);
    EXPECT_EQ(m.triangles.size(), 2u);
    EXPECT_EQ(m.vertices.size(), 4u);
    EXPECT_EQ(m.error_bound, 0.0);
    const MeshCheck c = check_mesh(hf, m);
    EXPECT_TRUE(c.ok(0.0)) << c.describe();
  }
}

// 3 x 3 zeros with the centre raised by 4 m:
//
//   (0,0) 0 --- (1,0) 0 --- (2,0) 0
//     |      \     |      \     |
//   (0,1) 0 --- (1,1) 4 --- (2,1) 0        cells split along (i,j)-(i+1,j+1)
//     |      \     |      \     |
//   (0,2) 0 --- (1,2) 0 --- (2,2) 0
//
// Removing the centre leaves only 0 m vertices around it, so the mesh is 0 at (1,1): error 4.
// A border midpoint, e.g. (1,0) -> (0,0), turns (1,0),(2,0),(2,1) into (0,0),(2,0),(2,1),
// whose edge (0,0)-(2,1) crosses x = 1 at y = 1/2 on the grid edge (1,0)-(1,1), where the full
// surface is (0 + 4)/2 = 2 and the edge 0: error 2; no sample changes (error 0 at samples).
// (1,0) -> (2,0) gives the edge (2,0)-(1,1), 2 at (1.5, 0.5) where the surface (on the
// diagonal (1,0)-(2,1)) is 0: error 2 again; (2,1) and the others are the same by the grid's
// 180-degree symmetry. So with the continuous metric the first collapse costs exactly 2; with
// the sample metric it costs 0. Every mesh has heights in [0,4] like the terrain, so no
// collapse costs more than 4, and the base mesh (four corners) costs exactly 4.
TEST(ProgressiveMesh, RaisedCentreKeptUntilItsErrorByHand) {
  const pm::Heightfield hf = grid(3, 3, {0, 0, 0, 0, 4, 0, 0, 0, 0});
  const std::uint32_t centre = idx(hf, 1, 1);
  for (auto metric : {pm::ErrorMetric::Continuous, pm::ErrorMetric::Samples}) {
    SCOPED_TRACE(metric == pm::ErrorMetric::Continuous ? "continuous" : "samples");
    pm::BuildOptions o;
    o.metric = metric;
    const pm::ProgressiveMesh p = pm::ProgressiveMesh::build(hf, o);
    ASSERT_EQ(p.vsplit_count(), 5u);
    EXPECT_EQ(p.collapses().front().error, metric == pm::ErrorMetric::Continuous ? 2.0 : 0.0);
    EXPECT_EQ(p.max_error(), 4.0);
    for (double E : {0.0, 1.0, 1.99, 2.0, 3.0, 3.99}) {
      const pm::TriangleMesh m = p.extract(E);
      EXPECT_TRUE(has_vertex(m, centre)) << "centre removed at E = " << E;
      const MeshCheck c = check_mesh(hf, m);
      EXPECT_TRUE(c.ok(E, metric == pm::ErrorMetric::Continuous)) << c.describe();
    }
    if (metric == pm::ErrorMetric::Continuous) {
      EXPECT_EQ(p.extract(1.99).triangles.size(), 8u);
    } else {
      EXPECT_LT(p.extract(0.0).triangles.size(), 8u);
    }
    const pm::TriangleMesh base = p.extract(4.0);
    EXPECT_FALSE(has_vertex(base, centre));
    EXPECT_EQ(base.triangles.size(), 2u);
    EXPECT_EQ(base.error_bound, 4.0);
    const MeshCheck c = check_mesh(hf, base);
    EXPECT_TRUE(c.ok(4.0)) << c.describe();
    EXPECT_EQ(c.max_sample_error, 4.0);
    EXPECT_EQ(c.worst_sample_col, 1);
    EXPECT_EQ(c.worst_sample_row, 1);
  }
}

TEST(ProgressiveMesh, FlatTerrainCollapsesAtZeroError) {
  const pm::Heightfield hf(40, 30);  // all zeros
  const pm::ProgressiveMesh p = pm::ProgressiveMesh::build(hf);
  for (const pm::Collapse& c : p.collapses()) ASSERT_EQ(c.error, 0.0);
  const pm::TriangleMesh m = p.extract(0.0);
  std::printf("  flat 40x30: extract(0) has %zu vertices, %zu triangles\n", m.vertices.size(),
              m.triangles.size());
  EXPECT_LE(m.triangles.size(), 8u);
  verify_pm(hf, p, "flat 40x30");
}

// The boundary of a mesh: every vertex on it (sample index) with its neighbours along
// boundary edges (edges of one face).
std::map<std::uint32_t, std::vector<std::uint32_t>> boundary_of(const pm::TriangleMesh& m) {
  std::map<std::pair<std::uint32_t, std::uint32_t>, int> uses;  // undirected edge -> faces
  for (const auto& t : m.triangles)
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = m.vertices[t[k]], b = m.vertices[t[(k + 1) % 3]];
      ++uses[{std::min(a, b), std::max(a, b)}];
    }
  std::map<std::uint32_t, std::vector<std::uint32_t>> ends;
  for (const auto& [e, n] : uses)
    if (n == 1) ends[e.first].push_back(e.second), ends[e.second].push_back(e.first);
  return ends;
}

// The boundary vertices where the outline turns: their two boundary neighbours are not on one
// line with them on either side, or they have more than two (a grid `width` samples wide).
std::vector<std::uint32_t> outline_turns(const pm::TriangleMesh& m, int width) {
  std::vector<std::uint32_t> turns;
  for (const auto& [v, nb] : boundary_of(m)) {
    const auto dx = [&](std::uint32_t s) { return long(s % width) - long(v % width); };
    const auto dy = [&](std::uint32_t s) { return long(s / width) - long(v / width); };
    const bool straight = nb.size() == 2 && dx(nb[0]) * dy(nb[1]) - dy(nb[0]) * dx(nb[1]) == 0 &&
                          dx(nb[0]) * dx(nb[1]) + dy(nb[0]) * dy(nb[1]) < 0;
    if (!straight) turns.push_back(v);
  }
  return turns;  // in increasing order
}

// A flat 40 x 30 grid with a rectangular hole (void samples at columns 15-24, rows 10-17), a
// notch in its west border (columns 0-1, rows 20-23) and a bow-tie (two void samples either
// side of (31, 5)). Every collapse costs 0, so the base mesh keeps what the boundary rule
// (grid_border.hpp) keeps: a boundary vertex moves only where the outline is straight through
// it: the base mesh keeps every turn of the full mesh's outline, its domain is still every
// face of the valid cells (the checker), and it keeps no vertex of a hole's straight edges. Both builders.
// Before the rule covered holes, every vertex of the hole's straight edges stayed at every level.
TEST(ProgressiveMesh, HolesKeepTheirOutlineAndLoseTheVerticesOfItsStraightEdges) {
  pm::Heightfield hf(40, 30);
  std::vector<std::uint8_t> mask(hf.size(), 1);
  const auto hole = [&](int c, int r) { mask[std::size_t(r) * 40 + c] = 0; };
  for (int r = 10; r <= 17; ++r)
    for (int c = 15; c <= 24; ++c) hole(c, r);
  for (int r = 20; r <= 23; ++r) hole(0, r), hole(1, r);
  hole(30, 5), hole(32, 5);
  hf.set_mask(mask);
  const pm::ProgressiveMesh fast = pm::ProgressiveMesh::build(hf);
  const pm::ProgressiveMesh reference = pm::build_with_decimater(hf);
  const pm::TriangleMesh full = fast.extract_after(0);
  const std::vector<std::uint32_t> turns = outline_turns(full, 40);
  std::printf("  40x30 with holes: %zu boundary vertices, %zu of them turns\n", boundary_of(full).size(),
              turns.size());
  for (const pm::ProgressiveMesh* p : {&fast, &reference}) {
    SCOPED_TRACE(p == &fast ? "ProgressiveMesh::build" : "build_with_decimater");
    for (const pm::Collapse& c : p->collapses()) ASSERT_EQ(c.error, 0.0);
    const pm::TriangleMesh base = p->extract_after(p->collapses().size());
    const MeshCheck c = check_mesh(hf, base, CheckOptions{.excluded_faces = p->dropped_faces()});
    EXPECT_TRUE(c.ok(0.0)) << c.describe();
    // Every turn stays (the outline keeps its shape), and no vertex of a hole's straight edges
    // does. (A vertex on a straight stretch of the grid's border may: in a domain that is not
    // convex a collapse can be blocked for good by a face it would flip, as happens to one
    // here in each builder; that was so before holes could thin out too.)
    const std::vector<std::uint32_t> base_turns = outline_turns(base, 40);
    EXPECT_EQ(base_turns, turns) << "the outline changed";
    std::size_t straight_on_holes = 0, straight_on_border = 0;
    for (const auto& [v, nb] : boundary_of(base)) {
      if (std::binary_search(turns.begin(), turns.end(), v)) continue;
      const int col = int(v % 40), row = int(v / 40);
      ++(col == 0 || col == 39 || row == 0 || row == 29 ? straight_on_border : straight_on_holes);
    }
    EXPECT_EQ(straight_on_holes, 0u) << "vertices of a hole's straight edges were kept";
    std::printf(
        "  %s: base mesh %zu vertices (%zu on straight stretches of the grid's border), %zu triangles\n",
        p == &fast ? "build" : "decimater", base.vertices.size(), straight_on_border, base.triangles.size());
  }
}

TEST(ProgressiveMesh, RejectsTooSmallGrids) {
  EXPECT_THROW(pm::ProgressiveMesh::build(pm::Heightfield(1, 5)), std::invalid_argument);
  EXPECT_THROW(pm::ProgressiveMesh::build(pm::Heightfield(5, 1)), std::invalid_argument);
  const pm::ProgressiveMesh p = pm::ProgressiveMesh::build(pm::Heightfield(3, 3));
  EXPECT_THROW(p.extract(-1.0), std::invalid_argument);
  EXPECT_THROW(p.extract_after(p.vsplit_count() + 1), std::invalid_argument);
}

// ------------------------------------------------------------------------------------------
// Generated terrains: the checker confirms every extraction.

struct TerrainCase {
  const char* name;
  int width, height;
  std::uint64_t seed;
  bool quantize;
  pm::ErrorMetric metric;
  bool holes;
};

std::ostream& operator<<(std::ostream& o, const TerrainCase& c) { return o << c.name; }

// A few holes: a disc, a rectangle, a lone sample, a notch in the west border, and two
// samples either side of (W-19, 12), which leaves that vertex with two separate fans of faces
// (a bow-tie: OpenMesh holds it as one vertex with two boundary gaps; any face it refused
// would be listed in dropped_faces() and leave the checker's domain).
void punch_holes(pm::Heightfield& hf) {
  const int W = hf.width(), H = hf.height();
  std::vector<std::uint8_t> mask(hf.size(), 1);
  auto hole = [&](int c, int r) {
    if (c >= 0 && r >= 0 && c < W && r < H) mask[std::size_t(r) * W + c] = 0, hf.at(c, r) = 0.0;
  };
  for (int r = 0; r < H; ++r)
    for (int c = 0; c < W; ++c)
      if ((c - W / 2) * (c - W / 2) + (r - H / 2) * (r - H / 2) <= 25) hole(c, r);
  for (int r = 8; r < 11; ++r)
    for (int c = 10; c < 14; ++c) hole(c, r);
  hole(W - 12, H - 9);
  for (int r = H / 3; r < H / 3 + 4; ++r) hole(0, r), hole(1, r);
  hole(W - 20, 12), hole(W - 18, 12);
  hf.set_mask(mask);
}

class GeneratedTerrain : public ::testing::TestWithParam<TerrainCase> {};

TEST_P(GeneratedTerrain, EveryExtractionWithinBoundCoversOnceAndIsWatertight) {
  const TerrainCase& tc = GetParam();
  pm::TerrainOptions to;
  to.width = tc.width, to.height = tc.height, to.seed = tc.seed, to.quantize_to_metres = tc.quantize;
  pm::Heightfield hf = pm::generate_terrain(to);
  if (tc.holes) punch_holes(hf);
  std::printf("  %s: seed %llu (printed so a failure can be replayed)\n", tc.name,
              (unsigned long long)tc.seed);
  pm::BuildOptions o;
  o.metric = tc.metric;
  const pm::ProgressiveMesh p = timed_build(hf, tc.name, o);
  verify_pm(hf, p, tc.name);
  if (tc.holes) {
    EXPECT_LT(p.full_vertex_count(), hf.size());
  }
}

INSTANTIATE_TEST_SUITE_P(
    ProgressiveMesh, GeneratedTerrain,
    ::testing::Values(
        TerrainCase{"g33x33_s1", 33, 33, 1, false, pm::ErrorMetric::Continuous, false},
        TerrainCase{"g33x33_s7_quantized", 33, 33, 7, true, pm::ErrorMetric::Continuous, false},
        TerrainCase{"g65x65_s2_quantized", 65, 65, 2, true, pm::ErrorMetric::Continuous, false},
        TerrainCase{"g65x65_s3", 65, 65, 3, false, pm::ErrorMetric::Continuous, false},
        TerrainCase{"g100x71_s4", 100, 71, 4, false, pm::ErrorMetric::Continuous, false},
        TerrainCase{"g100x71_s5_quantized", 100, 71, 5, true, pm::ErrorMetric::Continuous, false},
        TerrainCase{"g129x129_s6", 129, 129, 6, false, pm::ErrorMetric::Continuous, false},
        TerrainCase{"g129x129_s8_quantized", 129, 129, 8, true, pm::ErrorMetric::Continuous, false},
        TerrainCase{"g65x65_s9_samples", 65, 65, 9, false, pm::ErrorMetric::Samples, false},
        TerrainCase{"g129x129_s10_samples_quantized", 129, 129, 10, true, pm::ErrorMetric::Samples, false},
        TerrainCase{"g97x81_s11_holes", 97, 81, 11, false, pm::ErrorMetric::Continuous, true},
        TerrainCase{"g97x81_s12_holes_quantized", 97, 81, 12, true, pm::ErrorMetric::Continuous, true},
        TerrainCase{"g97x81_s13_holes_samples", 97, 81, 13, true, pm::ErrorMetric::Samples, true}),
    [](const ::testing::TestParamInfo<TerrainCase>& info) { return std::string(info.param.name); });

// Sea at 0 m, a lake at 123.4 m (a height no float holds exactly) and the same coast with holes in
// the sea: the builder takes a region whose samples all share one height as lying on every
// triangle and segment inside it, without measuring them (Builder::flat_box). Every extraction
// stays within its bound at every sample (the independent checker), flat or not, and wholly flat
// collapses record no error.
TEST(ProgressiveMesh, SeaAndLakeAreFlatAndWithinTheBound) {
  pm::TerrainOptions to;
  to.width = 129, to.height = 97, to.seed = 21, to.relief = 300.0;
  pm::Heightfield coast = pm::generate_terrain(to);
  double lo = 1e300, hi = -1e300;
  for (double z : coast.samples()) lo = std::min(lo, z), hi = std::max(hi, z);
  const double sea = lo + 0.4 * (hi - lo);
  for (int r = 0; r < coast.height(); ++r)
    for (int c = 0; c < coast.width(); ++c) {
      double& z = coast.at(c, r);
      z = z < sea ? 0.0 : z - sea;
      if ((c - 90) * (c - 90) + (r - 30) * (r - 30) < 120) z = 123.4;  // a lake, raised or dug
    }
  pm::Heightfield holed = coast;
  punch_holes(holed);
  for (const pm::Heightfield* hf : {&coast, &holed}) {
    const char* name = hf->has_holes() ? "coast with holes" : "coast";
    std::size_t flat_collapses = 0;
    const pm::ProgressiveMesh p = timed_build(*hf, name, {});
    for (const pm::Collapse& c : p.collapses())
      flat_collapses += (*hf)[c.u] == 0.0 && (*hf)[c.w] == 0.0 && c.error == 0.0;
    EXPECT_GT(flat_collapses, hf->size() / 4) << name;
    verify_pm(*hf, p, name);
  }
}

// The parallel build (vertical strips, merged, then joined) must give a PM as valid as the
// sequential one, and the same PM every time. 300 x 260 samples with threads = 2 takes the
// strip path (it needs >= 65536 samples and >= 128 columns per strip).
TEST(ProgressiveMesh, ParallelStripsGiveAValidDeterministicPm) {
  pm::TerrainOptions to;
  to.width = 300, to.height = 260, to.seed = 21, to.quantize_to_metres = true, to.relief = 600.0;
  std::printf("  generated 300x260, seed %llu, quantized\n", (unsigned long long)to.seed);
  const pm::Heightfield hf = pm::generate_terrain(to);
  pm::BuildOptions two, one;
  two.threads = 2, one.threads = 1;
  const pm::ProgressiveMesh a = pm::ProgressiveMesh::build(hf, two);
  const pm::ProgressiveMesh b = pm::ProgressiveMesh::build(hf, two);
  EXPECT_TRUE(a == b) << "two builds of the same terrain differ";
  verify_pm(hf, a, "g300x260_s21 threads=2");
  const pm::ProgressiveMesh c = pm::ProgressiveMesh::build(hf, one);
  verify_pm(hf, c, "g300x260_s21 threads=1");
  EXPECT_EQ(a.vsplit_count(), c.vsplit_count());
}

// Without parallel strips the whole grid is one greedy sequence: no column stays at full
// resolution. With strips, every sample of the cut column is still a vertex at an error below
// the strips' common error; without them only a few are (300 x 260, seed 21: the column is
// the one between the two strips, 149 or 150; we count the densest interior column).
TEST(ProgressiveMesh, WithoutParallelStripsNoColumnStaysAtFullResolution) {
  pm::TerrainOptions to;
  to.width = 300, to.height = 260, to.seed = 21, to.quantize_to_metres = true, to.relief = 600.0;
  const pm::Heightfield hf = pm::generate_terrain(to);
  pm::BuildOptions strips, whole;
  whole.parallel_strips = false;
  const pm::ProgressiveMesh a = pm::ProgressiveMesh::build(hf, strips);
  const pm::ProgressiveMesh b = pm::ProgressiveMesh::build(hf, whole);
  verify_pm(hf, b, "g300x260_s21 one sequence");
  whole.threads = 1;
  EXPECT_TRUE(pm::ProgressiveMesh::build(hf, whole) == b) << "the PM depends on the thread count";
  // Vertices per column of the extractions at E = 2 m: the strips' cut column keeps every
  // sample; the one-sequence PM keeps about as many there as in any other column.
  auto per_column = [&](const pm::ProgressiveMesh& p) {
    std::vector<int> n(std::size_t(hf.width()), 0);
    for (std::uint32_t v : p.extract(2.0).vertices) ++n[v % std::uint32_t(hf.width())];
    return n;
  };
  const std::vector<int> sa = per_column(a), sb = per_column(b);
  const std::size_t cut = std::size_t(std::max_element(sa.begin() + 1, sa.end() - 1) - sa.begin());
  std::vector<int> others(sb.begin() + 1, sb.end() - 1);
  std::sort(others.begin(), others.end());
  const int median = others[others.size() / 2];
  std::printf("  column %zu at E = 2 m: %d of %d samples with strips, %d without (median column %d)\n", cut,
              sa[cut], hf.height(), sb[cut], median);
  EXPECT_EQ(sa[cut], hf.height()) << "the cut column should be at full resolution (strips in use?)";
  EXPECT_LE(sb[cut], 2 * median);
}

// Grids with holes build in strips too (before, they always built whole, on one thread: a
// geographic DEM's tile in the --crs auto frame, whose footprint leaves void slivers along its
// edges, took twice as long). punch_holes()'s disc crosses the cut column (149); `pinch` adds a
// bow-tie on it, two void samples above and below (149, 100), which leaves that cut vertex
// with one face in each strip and none joining them.
TEST(ProgressiveMesh, GridsWithHolesBuildInStripsToo) {
  for (const bool pinch : {false, true}) {
    SCOPED_TRACE(pinch ? "a bow-tie on the cut column" : "holes off the cut column");
    pm::TerrainOptions to;
    to.width = 300, to.height = 260, to.seed = 22, to.quantize_to_metres = true, to.relief = 600.0;
    pm::Heightfield hf = pm::generate_terrain(to);
    punch_holes(hf);
    if (pinch) {
      std::vector<std::uint8_t> mask = hf.mask();
      mask[std::size_t(99) * 300 + 149] = mask[std::size_t(101) * 300 + 149] = 0;
      hf.set_mask(mask);
    }
    pm::BuildOptions two, one, whole;
    two.threads = 2, one.threads = 1, whole.parallel_strips = false;
    const pm::ProgressiveMesh a = pm::ProgressiveMesh::build(hf, two);
    verify_pm(hf, a, pinch ? "g300x260_s22 holes, pinch" : "g300x260_s22 holes");
    EXPECT_TRUE(pm::ProgressiveMesh::build(hf, one) == a) << "the PM depends on the thread count";
    std::size_t cut_vertices = 0, cut_samples = 0;  // of column 149 (at E = 2 m: all, with strips)
    for (std::uint32_t v : a.extract(2.0).vertices) cut_vertices += v % 300 == 149;
    for (int r = 0; r < 260; ++r) cut_samples += hf.valid(149, r);
    std::printf("  %s: %zu of the cut column's %zu samples are vertices at E = 2 m\n",
                pinch ? "pinch" : "holes", cut_vertices, cut_samples);
    if (!pinch) {  // (the whole build of the pinch case would only be printed: 10 s under ASan)
      EXPECT_EQ(cut_vertices, cut_samples) << "not built in strips";
      EXPECT_FALSE(pm::ProgressiveMesh::build(hf, whole) == a);
    }
  }
}

// ------------------------------------------------------------------------------------------
// Real SRTM tiles.

// 257 x 257 around Mount Washington (44.27 N, 71.30 W: row ~876, col ~840 of N44W072).
TEST(ProgressiveMeshRealTile, WhiteMountainsCrop257) {
  const auto raw = read_hgt("N44W072.hgt");
  if (!raw) GTEST_SKIP() << "N44W072.hgt not in " << TERRALOD_DATA_DIR;
  const pm::Heightfield hf = crop(*raw, 712, 750, 257, 257, Voids::Fill);
  const pm::ProgressiveMesh p = timed_build(hf, "N44W072 crop 257");
  verify_pm(hf, p, "N44W072 crop 257");
}

// 257 x 257 of Kauai's coast, where the tile's voids are (rows 900.., cols 300..): filled from
// their neighbours, or kept as holes, which the PM leaves out.
void verify_kauai_crop(Voids mode) {
  const auto raw = read_hgt("N22W160.hgt");
  if (!raw) GTEST_SKIP() << "N22W160.hgt not in " << TERRALOD_DATA_DIR;
  std::size_t voids = 0;
  const pm::Heightfield hf = crop(*raw, 300, 900, 257, 257, mode, &voids);
  const bool holes = mode == Voids::Holes;
  if (holes) {
    ASSERT_TRUE(hf.has_holes());
  } else {
    EXPECT_GT(voids, 500u) << "the crop should contain voids";
    EXPECT_FALSE(hf.has_holes());
  }
  const std::string what =
      "N22W160 crop 257, " + std::to_string(voids) + (holes ? " voids as holes" : " voids filled");
  const pm::ProgressiveMesh p = timed_build(hf, what);
  verify_pm(hf, p, holes ? "N22W160 crop 257 holes" : "N22W160 crop 257 filled");
  if (holes) {
    EXPECT_LE(p.full_vertex_count(), hf.size() - voids);
  }
}

TEST(ProgressiveMeshRealTile, KauaiVoidsFilledCrop257) { verify_kauai_crop(Voids::Fill); }

TEST(ProgressiveMeshRealTile, KauaiVoidsAsHolesCrop257) { verify_kauai_crop(Voids::Holes); }

// The whole 1201 x 1201 White Mountains tile (about a minute: build plus seven checks).
TEST(ProgressiveMeshRealTile, RealTileFullN44W072) {
  const auto raw = read_hgt("N44W072.hgt");
  if (!raw) GTEST_SKIP() << "N44W072.hgt not in " << TERRALOD_DATA_DIR;
  const pm::Heightfield hf = crop(*raw, 0, 0, kHgt, kHgt, Voids::Fill);
  const auto t0 = std::chrono::steady_clock::now();
  const pm::ProgressiveMesh p = pm::ProgressiveMesh::build(hf);
  std::printf("  N44W072 full tile: build %.0f ms, %zu collapses\n", ms_since(t0), p.vsplit_count());
  const Verified v = verify_pm(hf, p, "N44W072 full 1201");
  ASSERT_EQ(v.triangles.size(), kErrors.size());
  // Sanity of the numbers, not a read-off: a 100 m mesh of a 1.8 km relief is far smaller
  // than the 2.88 M triangles of the grid, and 0.5 m already drops a good share of them.
  EXPECT_LT(v.triangles.back(), v.triangles.front() / 20);
}

}  // namespace
