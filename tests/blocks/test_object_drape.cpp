// Draped lines (blocks/object_drape.hpp) on a real block database: along a flight with
// geomorphs and block loads, every ribbon vertex lies on the drawn mesh, every ribbon triangle
// lies within one drawn triangle (so its interior is on the mesh too), the ribbon covers its
// plan shape wherever terrain is drawn (no gap where it crosses drawn edges or turns) and
// nothing farther than half its width from the line; straight ribbons have exactly their area.
// Every check scans the drawn triangles by brute force, independently of the draping code.
// Also: TerrainRuntime::drawn_triangles_in returns every drawn triangle under a box.
//
// The terrain: 129 x 129 generated samples (30 m, heights in whole metres), blocks of 33
// samples, sample (col, row) at easting 500015 + 30 col, northing 5001935 - 30 row (UTM-sized
// coordinates, so precision is tested where it is hardest). Lines are given in (col, row).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "object_terrain.hpp"
#include "printed_seed.hpp"
#include "run_command.hpp"
#include "terralod/blocks/object_drape.hpp"
#include "terralod/blocks/terrain_runtime.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace {

namespace tb = terralod::blocks;
namespace tp = terralod::pm;
namespace tt = terralod::test;

constexpr int kSize = 129;
constexpr double kSpacing = 30.0;
const tp::GridTransform kUtm = tt::object_terrain_transform();  // kSpacing-metre samples

using Scene = tt::ObjectTerrain;

const Scene& scene() {
  static const Scene s = tt::make_object_terrain("drape", 33);
  return s;
}

tb::WorldPoint at(double col, double row) {
  const auto [x, y] = kUtm.to_world(col, row);
  return {x, y};
}

std::vector<tb::WorldPoint> line_at(const std::vector<std::pair<double, double>>& cr) {
  std::vector<tb::WorldPoint> l;
  for (const auto& [c, r] : cr) l.push_back(at(c, r));
  return l;
}

double cross2(double ax, double ay, double bx, double by, double cx, double cy) {
  return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
}

// Whether plan point (x, y) is in triangle a, b, c (either orientation), within `tol` metres
// of its edges (negative: strictly inside by that much).
bool in_triangle(const tp::Vec3& a, const tp::Vec3& b, const tp::Vec3& c, double x, double y, double tol) {
  const double det = cross2(a.x, a.y, b.x, b.y, c.x, c.y);
  if (det == 0) return false;
  const double s = det > 0 ? 1.0 : -1.0;
  auto edge = [&](const tp::Vec3& p, const tp::Vec3& q) {
    return s * cross2(p.x, p.y, q.x, q.y, x, y) / std::hypot(q.x - p.x, q.y - p.y) >= -tol;
  };
  return edge(a, b) && edge(b, c) && edge(c, a);
}

bool outside_box(const tp::Vec3& a, const tp::Vec3& b, const tp::Vec3& c, double x, double y, double tol) {
  return x < std::min({a.x, b.x, c.x}) - tol || x > std::max({a.x, b.x, c.x}) + tol ||
         y < std::min({a.y, b.y, c.y}) - tol || y > std::max({a.y, b.y, c.y}) + tol;
}

// The drawn triangle containing plan (x, y) (within tol metres), by a scan of all of them: its
// index, or -1.
long drawn_at(const tb::DrawnMesh& m, double x, double y, double tol) {
  for (std::size_t f = 0; f < m.triangles.size(); ++f) {
    const auto& t = m.triangles[f];
    const tp::Vec3 &a = m.positions[t[0]], &b = m.positions[t[1]], &c = m.positions[t[2]];
    if (!outside_box(a, b, c, x, y, tol) && in_triangle(a, b, c, x, y, tol)) return long(f);
  }
  return -1;
}

double plane_z(const tb::DrawnMesh& m, long f, double x, double y) {
  const auto& t = m.triangles[std::size_t(f)];
  const tp::Vec3 &a = m.positions[t[0]], &b = m.positions[t[1]], &c = m.positions[t[2]];
  const double det = cross2(a.x, a.y, b.x, b.y, c.x, c.y);
  const double l1 = cross2(a.x, a.y, x, y, c.x, c.y) / det, l2 = cross2(a.x, a.y, b.x, b.y, x, y) / det;
  return (1 - l1 - l2) * a.z + l1 * b.z + l2 * c.z;
}

// Plan distance from (x, y) to the polyline.
double distance_to_line(const std::vector<tb::WorldPoint>& l, double x, double y) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < l.size(); ++i) {
    const tb::WorldPoint a = l[i], b = l[std::min(i + 1, l.size() - 1)];
    const double dx = b.x - a.x, dy = b.y - a.y, len2 = dx * dx + dy * dy;
    const double t = len2 == 0 ? 0.0 : std::clamp(((x - a.x) * dx + (y - a.y) * dy) / len2, 0.0, 1.0);
    best = std::min(best, std::hypot(x - a.x - t * dx, y - a.y - t * dy));
  }
  return best;
}

// A point of the ribbon's plan shape as the header defines it: uniform in a segment's rectangle,
// or in the triangle (vertex, the two rectangle corners on the outer side) of a join, which the
// round join contains.
struct ShapeSampler {
  std::vector<std::array<tb::WorldPoint, 4>> quads;  // rectangles (corners in order)
  std::vector<std::array<tb::WorldPoint, 3>> wedges;
  ShapeSampler(const std::vector<tb::WorldPoint>& line, double h) {
    std::vector<tb::WorldPoint> p;
    for (const tb::WorldPoint& q : line)
      if (p.empty() || !(p.back() == q)) p.push_back(q);
    for (std::size_t i = 0; i + 1 < p.size(); ++i) {
      const double dx = p[i + 1].x - p[i].x, dy = p[i + 1].y - p[i].y, len = std::hypot(dx, dy);
      const double nx = -dy / len * h, ny = dx / len * h;
      quads.push_back({{{p[i].x - nx, p[i].y - ny},
                        {p[i + 1].x - nx, p[i + 1].y - ny},
                        {p[i + 1].x + nx, p[i + 1].y + ny},
                        {p[i].x + nx, p[i].y + ny}}});
      if (i + 2 < p.size()) {
        const double ex = p[i + 2].x - p[i + 1].x, ey = p[i + 2].y - p[i + 1].y, elen = std::hypot(ex, ey);
        const double mx = -ey / elen * h, my = ex / elen * h;
        const double turn = dx * ey - dy * ex;
        const double s = turn > 0 ? -1.0 : 1.0;  // the outer side
        wedges.push_back({{p[i + 1],
                           {p[i + 1].x + s * nx, p[i + 1].y + s * ny},
                           {p[i + 1].x + s * mx, p[i + 1].y + s * my}}});
      }
    }
  }
  tb::WorldPoint sample(std::mt19937& rng) const {
    std::uniform_real_distribution<double> u(0, 1);
    const std::size_t k =
        std::uniform_int_distribution<std::size_t>(0, quads.size() + wedges.size() - 1)(rng);
    if (k < quads.size()) {
      const auto& q = quads[k];
      const double a = u(rng), b = u(rng);
      return {q[0].x + a * (q[1].x - q[0].x) + b * (q[3].x - q[0].x),
              q[0].y + a * (q[1].y - q[0].y) + b * (q[3].y - q[0].y)};
    }
    const auto& w = wedges[k - quads.size()];
    double a = u(rng), b = u(rng);
    if (a + b > 1) a = 1 - a, b = 1 - b;
    return {w[0].x + a * (w[1].x - w[0].x) + b * (w[2].x - w[0].x),
            w[0].y + a * (w[1].y - w[0].y) + b * (w[2].y - w[0].y)};
  }
};

struct Line {
  std::string what;
  std::vector<tb::WorldPoint> points;
  double width_m;
};

std::vector<Line> test_lines() {
  return {
      {"long diagonal", line_at({{5, 7}, {120, 118.3}}), 12.0},
      {"zig-zag", line_at({{20, 100}, {40, 60}, {45, 100}, {50, 60.5}, {70, 95}, {72, 64}, {71.5, 100}}),
       25.0},
      {"reversal", line_at({{90, 20}, {100, 31}, {90, 20}, {95, 12}}), 18.0},
      {"along a block border", line_at({{3, 64}, {125, 64}}), 9.0},
      {"side on a block border", line_at({{10, 32 - 8.0 / kSpacing}, {118, 32 - 8.0 / kSpacing}}), 16.0},
      {"partly outside", line_at({{-20, 50}, {60, 40}, {150, 45}, {150, 80}}), 30.0},
      {"zero-length segments", line_at({{30, 30}, {30, 30}, {50, 35}, {50, 35}, {50, 35}, {60, 20}}), 6.0},
      {"one point", line_at({{40, 40}, {40, 40}}), 10.0},
      {"wide, turning", line_at({{100, 110}, {115, 70}, {80, 75}, {110, 105}}), 150.0},
  };
}

// The checks of one frame: `out` holds the ribbons of `lines`, object k for lines[k].
void check_frame(const tb::TerrainRuntime& rt, const std::vector<Line>& lines, const tb::ObjectMesh& out,
                 std::mt19937& rng, const std::string& frame, std::size_t& samples_over_terrain) {
  const tb::DrawnMesh& m = rt.drawn_mesh();
  ASSERT_EQ(out.normals.size(), out.positions.size());
  ASSERT_EQ(out.triangle_object.size(), out.triangles.size());
  // (a) every vertex on the displayed mesh.
  for (std::size_t v = 0; v < out.positions.size(); ++v) {
    const tp::Vec3 p = out.positions[v];
    const long f = drawn_at(m, p.x, p.y, 1e-7);
    ASSERT_GE(f, 0) << frame << ": vertex " << v << " over nothing drawn";
    ASSERT_NEAR(p.z, plane_z(m, f, p.x, p.y), 1e-6) << frame << ": vertex " << v << " off the mesh";
  }
  std::vector<std::vector<std::size_t>> by_line(lines.size());
  for (std::size_t t = 0; t < out.triangles.size(); ++t) {
    ASSERT_LT(out.triangle_object[t], lines.size());
    by_line[out.triangle_object[t]].push_back(t);
    const auto& tri = out.triangles[t];
    const tp::Vec3 &a = out.positions[tri[0]], &b = out.positions[tri[1]], &c = out.positions[tri[2]];
    // CCW from above, normals up and perpendicular to the triangle.
    ASSERT_GT(cross2(a.x, a.y, b.x, b.y, c.x, c.y), 0) << frame << ": triangle " << t;
    for (std::uint32_t v : tri) {
      const tp::Vec3 n = out.normals[v];
      EXPECT_NEAR(tp::dot(n, n), 1.0, 1e-9);
      EXPECT_GT(n.z, 0);
      EXPECT_NEAR(tp::dot(n, tp::sub(b, a)), 0, 1e-6 * (1 + std::hypot(b.x - a.x, b.y - a.y)));
      EXPECT_NEAR(tp::dot(n, tp::sub(c, a)), 0, 1e-6 * (1 + std::hypot(c.x - a.x, c.y - a.y)));
    }
    // Within one drawn triangle in plan: then, its vertices being on that triangle's plane, the
    // whole ribbon triangle is on the mesh (a ribbon cutting across a drawn edge is caught here).
    bool inside_one = false;
    for (std::size_t f = 0; f < m.triangles.size() && !inside_one; ++f) {
      const auto& d = m.triangles[f];
      const tp::Vec3 &p = m.positions[d[0]], &q = m.positions[d[1]], &r = m.positions[d[2]];
      inside_one = !outside_box(p, q, r, a.x, a.y, 1e-7) && in_triangle(p, q, r, a.x, a.y, 1e-7) &&
                   in_triangle(p, q, r, b.x, b.y, 1e-7) && in_triangle(p, q, r, c.x, c.y, 1e-7);
    }
    ASSERT_TRUE(inside_one) << frame << ": ribbon triangle " << t << " ("
                            << lines[out.triangle_object[t]].what << ") crosses a drawn edge";
  }
  std::uniform_real_distribution<double> u(0, 1);
  for (std::size_t k = 0; k < lines.size(); ++k) {
    const Line& l = lines[k];
    const double h = l.width_m / 2;
    // (b) nothing farther than h from the line: vertices and random points of each triangle.
    for (std::size_t t : by_line[k]) {
      const auto& tri = out.triangles[t];
      const tp::Vec3 &a = out.positions[tri[0]], &b = out.positions[tri[1]], &c = out.positions[tri[2]];
      for (int s = 0; s < 4; ++s) {
        double wa = s == 0 ? 1.0 / 3 : u(rng), wb = s == 0 ? 1.0 / 3 : u(rng);
        if (wa + wb > 1) wa = 1 - wa, wb = 1 - wb;
        for (const auto& [x, y] : {std::pair{a.x, a.y}, std::pair{b.x, b.y},
                                   std::pair{a.x + wa * (b.x - a.x) + wb * (c.x - a.x),
                                             a.y + wa * (b.y - a.y) + wb * (c.y - a.y)}})
          ASSERT_LE(distance_to_line(l.points, x, y), h + 1e-6) << frame << ": " << l.what;
      }
    }
    // (b) no gap: random points of the shape over drawn terrain are in a ribbon triangle.
    const ShapeSampler shape(l.points, h);
    if (shape.quads.empty()) {
      EXPECT_TRUE(by_line[k].empty()) << frame << ": " << l.what;
      continue;
    }
    for (int s = 0; s < 300; ++s) {
      const tb::WorldPoint p = shape.sample(rng);
      if (drawn_at(m, p.x, p.y, -1e-6) < 0) continue;  // not clearly over drawn terrain
      ++samples_over_terrain;
      bool covered = false;
      for (std::size_t t : by_line[k]) {
        const auto& tri = out.triangles[t];
        const tp::Vec3 &a = out.positions[tri[0]], &b = out.positions[tri[1]], &c = out.positions[tri[2]];
        if (!outside_box(a, b, c, p.x, p.y, 1e-9) && in_triangle(a, b, c, p.x, p.y, 1e-9)) {
          covered = true;
          break;
        }
      }
      ASSERT_TRUE(covered) << frame << ": " << l.what << ": a gap at (" << p.x << ", " << p.y << ")";
    }
  }
}

tp::Camera camera_at(const Scene& s, double col, double row, double above, double yaw, double pitch) {
  return tt::camera_over(s.hf, col, row, above, yaw, pitch);
}

TEST(ObjectDrape, RibbonsLieOnTheDrawnMeshWithoutGapsAlongAFlightWithGeomorphsAndLoads) {
  const Scene& s = scene();
  tb::RuntimeOptions ro;
  ro.morph_seconds = 0.5;
  tb::TerrainRuntime rt(s.db, ro);
  const std::vector<Line> lines = test_lines();
  std::vector<tb::DrapedLine> batch;
  for (std::size_t k = 0; k < lines.size(); ++k)
    batch.push_back({lines[k].points, lines[k].width_m, std::uint32_t(k)});
  std::mt19937 rng = tt::printed_seed_rng(19);
  std::size_t morph_frames = 0, missing_frames = 0, samples = 0, triangles = 0;
  for (int f = 0; f < 10; ++f) {
    tp::Camera cam = camera_at(s, 15 + 9 * f, 120 - 8 * f, 500.0 + 60 * f, 30.0 + 12 * f, -35.0);
    rt.fit_camera(cam);
    const tp::View view(cam);
    const tb::RuntimeFrameStats st =
        f % 3 == 2 ? rt.update(view, f / 60.0) : rt.update_until_loaded(view, f / 60.0);
    morph_frames += rt.stats().moving_vertices > 0;
    missing_frames += st.missing_in_view > 0;
    tb::ObjectMesh out;
    const tb::DrapeStats ds = tb::drape_lines(rt, batch, out);
    EXPECT_EQ(ds.triangles, out.triangles.size());
    EXPECT_LE(ds.clips, ds.drawn_triangles_tested);
    triangles += out.triangles.size();
    // The one-line form appends the same ribbon.
    tb::ObjectMesh one;
    one.positions.push_back({1, 2, 3});  // appended to, not cleared
    one.normals.push_back({0, 0, 1});
    tb::drape_line(rt, lines[1].points, lines[1].width_m, 7, one);
    std::size_t zigzag = 0;
    for (std::uint32_t o : out.triangle_object) zigzag += o == 1;
    EXPECT_EQ(one.triangles.size(), zigzag);
    EXPECT_EQ(one.positions[0].z, 3.0);
    for (std::size_t t = 0; t < one.triangles.size(); ++t) {
      EXPECT_EQ(one.triangle_object[t], 7u);
      EXPECT_GE(std::min({one.triangles[t][0], one.triangles[t][1], one.triangles[t][2]}), 1u);
    }
    check_frame(rt, lines, out, rng, "frame " + std::to_string(f), samples);
    if (HasFatalFailure()) return;
  }
  EXPECT_GT(morph_frames, 0u) << "the flight must exercise geomorphs";
  EXPECT_GT(missing_frames, 0u) << "the flight must draw blocks still loading";
  EXPECT_GT(samples, 5000u) << "the gap check must sample ribbons over drawn terrain";
  EXPECT_GT(triangles, 5000u);
}

// Seen from straight above, high: the whole terrain is drawn, so a straight ribbon inside it
// has exactly its plan area, length x width, and an L turn adds its round join's polygon.
TEST(ObjectDrape, StraightRibbonsHaveTheirAreaAndJoinsTheirSector) {
  const Scene& s = scene();
  tb::TerrainRuntime rt(s.db);
  tp::Camera cam = camera_at(s, 64, 64, 9000.0, 0.0, -90.0);
  rt.fit_camera(cam);
  rt.update_until_loaded(tp::View(cam), 0.0);
  const tb::DrawnMesh& m = rt.drawn_mesh();
  double drawn = 0;
  for (const auto& t : m.triangles) {
    const tp::Vec3 &a = m.positions[t[0]], &b = m.positions[t[1]], &c = m.positions[t[2]];
    drawn += std::abs(cross2(a.x, a.y, b.x, b.y, c.x, c.y)) / 2;
  }
  ASSERT_NEAR(drawn, std::pow((kSize - 1) * kSpacing, 2), 1e-3) << "the whole terrain must be drawn";
  auto area = [](const tb::ObjectMesh& o) {
    double a = 0;
    for (const auto& t : o.triangles) {
      const tp::Vec3 &p = o.positions[t[0]], &q = o.positions[t[1]], &r = o.positions[t[2]];
      a += cross2(p.x, p.y, q.x, q.y, r.x, r.y) / 2;
    }
    return a;
  };
  struct Case {
    std::vector<tb::WorldPoint> points;
    double width, expected;
  };
  const double d1 = std::hypot(100.0, 70.0) * kSpacing, h = 8.5;
  const std::vector<Case> cases = {
      {line_at({{10, 20}, {110, 90}}), 2 * h, d1 * 2 * h},
      {line_at({{10, 20}, {60, 55}, {110, 90}}), 2 * h, d1 * 2 * h},  // a straight vertex: no join
      {line_at({{7.3, 3}, {7.3, 125}}), 4.0, 122 * kSpacing * 4.0},
      // An L (right turn seen from above: east, then south): two rectangles overlapping in an
      // h x h square inside the turn, plus a quarter-disc join of 4 arc steps of 22.5 degrees.
      {line_at({{20, 20}, {60, 20}, {60, 80}}), 2 * h,
       (40 + 60) * kSpacing * 2 * h + 2 * h * h * std::sin(std::numbers::pi / 8)},
  };
  for (std::size_t k = 0; k < cases.size(); ++k) {
    tb::ObjectMesh out;
    tb::drape_line(rt, cases[k].points, cases[k].width, 0, out);
    EXPECT_NEAR(area(out), cases[k].expected, 1e-6 * cases[k].expected) << "case " << k;
  }
}

// drawn_triangles_in: every drawn triangle whose plan box meets a random box (some partly or
// wholly off the terrain) is returned, sorted and once.
TEST(ObjectDrape, DrawnTrianglesInReturnsEveryTriangleUnderABox) {
  const Scene& s = scene();
  tb::TerrainRuntime rt(s.db);
  tp::Camera cam = camera_at(s, 20, 110, 600.0, 45.0, -30.0);
  rt.fit_camera(cam);
  rt.update_until_loaded(tp::View(cam), 0.0);
  const tb::DrawnMesh& m = rt.drawn_mesh();
  ASSERT_GT(m.triangles.size(), 100u);
  std::mt19937 rng = tt::printed_seed_rng(23);
  std::uniform_real_distribution<double> pos(-20, kSize + 20), size(0, 25);
  std::vector<std::uint32_t> got;
  std::size_t found = 0;
  for (int k = 0; k < 300; ++k) {
    const double c = pos(rng), r = pos(rng);
    const tb::WorldPoint p = at(c, r), q = at(c + size(rng), r + size(rng));
    rt.drawn_triangles_in(q.x, p.y, p.x, q.y, got);  // corners in any order
    EXPECT_TRUE(std::is_sorted(got.begin(), got.end()));
    EXPECT_EQ(std::adjacent_find(got.begin(), got.end()), got.end());
    const double x0 = std::min(p.x, q.x), x1 = std::max(p.x, q.x), y0 = std::min(p.y, q.y),
                 y1 = std::max(p.y, q.y);
    for (std::size_t f = 0; f < m.triangles.size(); ++f) {
      const auto& t = m.triangles[f];
      const tp::Vec3 &a = m.positions[t[0]], &b = m.positions[t[1]], &e = m.positions[t[2]];
      if (std::max({a.x, b.x, e.x}) < x0 || std::min({a.x, b.x, e.x}) > x1 ||
          std::max({a.y, b.y, e.y}) < y0 || std::min({a.y, b.y, e.y}) > y1)
        continue;
      ++found;
      ASSERT_TRUE(std::binary_search(got.begin(), got.end(), std::uint32_t(f)))
          << "box " << k << ": drawn triangle " << f << " missing";
    }
  }
  EXPECT_GT(found, 300u);
}

}  // namespace
