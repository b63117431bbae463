// Independent brute-force screen-space error checker (see screen_error_checker.hpp).
#include "screen_error_checker.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <glm/ext/matrix_clip_space.hpp>
#include <glm/ext/matrix_transform.hpp>
#include <glm/glm.hpp>
#include <limits>
#include <numbers>
#include <sstream>

#include "terralod/pm/height_query.hpp"

namespace terralod::test {
namespace {

std::int64_t floor_div(std::int64_t a, std::int64_t b) {  // b > 0
  const std::int64_t q = a / b;
  return (a % b != 0 && a < 0) ? q - 1 : q;
}

struct P {
  std::int64_t x, y;
};
std::int64_t orient(P a, P b, P c) { return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x); }

}  // namespace

ScreenProjector::ScreenProjector(const pm::Camera& cam) : cam_(cam) {
  const double yaw = glm::radians(cam.yaw_deg), pitch = glm::radians(cam.pitch_deg);
  const glm::dvec3 eye(cam.x, cam.y, cam.z);
  // Yaw clockwise from north (+y) towards east (+x); pitch above the horizon.
  const glm::dvec3 fwd(std::sin(yaw) * std::cos(pitch), std::cos(yaw) * std::cos(pitch), std::sin(pitch));
  // The image's up: perpendicular to fwd in the vertical plane through it (no roll).
  const glm::dvec3 up(-std::sin(yaw) * std::sin(pitch), -std::cos(yaw) * std::sin(pitch), std::cos(pitch));
  const glm::dmat4 view = glm::lookAt(eye, eye + fwd, up);
  const glm::dmat4 proj = glm::perspective(
      glm::radians(cam.fovy_deg), double(cam.width_px) / double(cam.height_px), cam.near_m, cam.far_m);
  // The ground scale (pm/view.hpp): a world point p is seen at eye + G (p - eye), G acting on
  // x and y. Built here as its own matrix, not through pm::GroundScale's helpers.
  glm::dmat4 ground(1.0);  // column-major: ground[column][row]
  ground[0][0] = cam.ground.xx, ground[1][0] = cam.ground.xy;
  ground[0][1] = cam.ground.xy, ground[1][1] = cam.ground.yy;
  const glm::dmat4 about_eye =
      glm::translate(glm::dmat4(1.0), eye) * ground * glm::translate(glm::dmat4(1.0), -eye);
  const glm::dmat4 m = proj * view * about_eye;
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) m_[c * 4 + r] = m[c][r];
}

namespace {
glm::dvec4 apply(const std::array<double, 16>& m, double x, double y, double z) {
  glm::dvec4 out(0.0);
  const double in[4] = {x, y, z, 1.0};
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) out[r] += m[c * 4 + r] * in[c];
  return out;
}
}  // namespace

bool ScreenProjector::project(double x, double y, double z, double& px, double& py) const {
  const glm::dvec4 c = apply(m_, x, y, z);
  if (!(c.w > 0.0)) return false;
  px = (c.x / c.w + 1.0) * 0.5 * cam_.width_px;
  py = (1.0 - c.y / c.w) * 0.5 * cam_.height_px;
  return true;
}

bool ScreenProjector::inside(double x, double y, double z) const {
  const glm::dvec4 c = apply(m_, x, y, z);
  return c.w > 0.0 && std::abs(c.x) <= c.w && std::abs(c.y) <= c.w && std::abs(c.z) <= c.w;
}

double ScreenProjector::vertical_segment_px(double x, double y, double z0, double z1) const {
  const glm::dvec4 a = apply(m_, x, y, z0), b = apply(m_, x, y, z1);
  // Liang-Barsky in homogeneous clip space: g(s) = g(a) + s (g(b) - g(a)) >= 0 for the six
  // planes w +- x, w +- y, w +- z.
  double lo = 0.0, hi = 1.0;
  const double ga[6] = {a.w + a.x, a.w - a.x, a.w + a.y, a.w - a.y, a.w + a.z, a.w - a.z};
  const double gb[6] = {b.w + b.x, b.w - b.x, b.w + b.y, b.w - b.y, b.w + b.z, b.w - b.z};
  for (int k = 0; k < 6; ++k) {
    if (ga[k] < 0 && gb[k] < 0) return 0.0;
    if (ga[k] < 0)
      lo = std::max(lo, ga[k] / (ga[k] - gb[k]));
    else if (gb[k] < 0)
      hi = std::min(hi, ga[k] / (ga[k] - gb[k]));
  }
  if (lo > hi) return 0.0;
  const glm::dvec4 p = a + lo * (b - a), q = a + hi * (b - a);
  const double px = (p.x / p.w - q.x / q.w) * 0.5 * cam_.width_px;
  const double py = (p.y / p.w - q.y / q.w) * 0.5 * cam_.height_px;
  return std::hypot(px, py);
}

std::string ScreenCheck::describe() const {
  std::ostringstream s;
  s << "max_error_px " << max_error_px << " at sample (" << worst_col << "," << worst_row << ") of triangle "
    << worst_triangle << " (vertical error " << worst_error_m << " m)\n"
    << "max_error_m (visible) " << max_error_m << "\nsamples_measured " << samples_measured
    << "\nsegments_visible " << segments_visible << "\ntriangles_visible " << triangles_visible << "\n";
  return s.str();
}

ScreenCheck check_screen_error(const pm::Heightfield& hf, const pm::TriangleMesh& mesh,
                               const ScreenProjector& cam) {
  ScreenCheck r;
  const std::int64_t W = hf.width();
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    P v[3];
    long double z[3];
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t s = mesh.vertices[mesh.triangles[t][k]];
      v[k] = {std::int64_t(s % W), std::int64_t(s / W)};
      z[k] = hf[s];
    }
    const std::int64_t A = orient(v[0], v[1], v[2]);
    if (A <= 0) continue;  // check_mesh reports flipped and degenerate triangles
    const std::int64_t y0 = std::min({v[0].y, v[1].y, v[2].y}), y1 = std::max({v[0].y, v[1].y, v[2].y});
    const std::int64_t x0 = std::min({v[0].x, v[1].x, v[2].x}), x1 = std::max({v[0].x, v[1].x, v[2].x});
    bool visible = false;
    for (std::int64_t y = y0; y <= y1; ++y) {
      // Edge e from v[e] to v[e+1]: orient(v[e], v[e+1], (x, y)) = k x + m >= 0.
      std::int64_t lo = x0, hi = x1;
      for (int e = 0; e < 3; ++e) {
        const P s = v[e], d = v[(e + 1) % 3];
        const std::int64_t k = -(d.y - s.y), m = (d.x - s.x) * (y - s.y) + (d.y - s.y) * s.x;
        if (k > 0)
          lo = std::max(lo, -floor_div(m, k));
        else if (k < 0)
          hi = std::min(hi, floor_div(m, -k));
        else if (m < 0)
          hi = lo - 1;
      }
      for (std::int64_t x = lo; x <= hi; ++x) {
        const P p{x, y};
        const std::int64_t w0 = orient(v[1], v[2], p), w1 = orient(v[2], v[0], p), w2 = orient(v[0], v[1], p);
        if (w0 < 0 || w1 < 0 || w2 < 0) continue;
        const std::size_t idx = std::size_t(y * W + x);
        if (!hf.valid(idx)) continue;
        ++r.samples_measured;
        const long double hm = (w0 * z[0] + w1 * z[1] + w2 * z[2]) / (long double)A;
        const double zs = hf[idx];
        const auto [wx, wy] = hf.transform.to_world(double(x), double(y));
        const double px = cam.vertical_segment_px(wx, wy, double(hm), zs);
        const bool in = px > 0.0 || cam.inside(wx, wy, zs);
        if (!in) continue;
        visible = true;
        ++r.segments_visible;
        const double em = double(std::fabs(hm - (long double)zs));
        r.max_error_m = std::max(r.max_error_m, em);
        if (px > r.max_error_px) {
          r.max_error_px = px;
          r.worst_col = int(x), r.worst_row = int(y);
          r.worst_triangle = t;
          r.worst_error_m = em;
        }
      }
    }
    r.triangles_visible += visible;
  }
  return r;
}

std::array<double, 2> world_to_index(const pm::Heightfield& hf, double x, double y) {
  const auto [col, row] = pm::world_to_grid(hf.transform, x, y);
  return {col, row};
}

SurfaceSamples surface_at_samples(const pm::Heightfield& hf, const std::vector<std::array<double, 3>>& pos,
                                  const std::vector<std::array<std::uint32_t, 3>>& triangles) {
  SurfaceSamples r;
  const int W = hf.width(), H = hf.height();
  r.height.assign(hf.size(), std::numeric_limits<double>::quiet_NaN());
  for (const auto& t : triangles) {
    const auto &a = pos[t[0]], &b = pos[t[1]], &c = pos[t[2]];
    const double area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    if (area == 0.0) {
      ++r.degenerate;
      continue;
    }
    if (area < 0.0) ++r.flipped;
    const int x0 = std::max(0, int(std::ceil(std::min({a[0], b[0], c[0]}) - 1e-9)));
    const int x1 = std::min(W - 1, int(std::floor(std::max({a[0], b[0], c[0]}) + 1e-9)));
    const int y0 = std::max(0, int(std::ceil(std::min({a[1], b[1], c[1]}) - 1e-9)));
    const int y1 = std::min(H - 1, int(std::floor(std::max({a[1], b[1], c[1]}) + 1e-9)));
    const double tol = -1e-12 * std::abs(area);
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        // Barycentric weights, each with the sign of the area.
        const double wa = ((b[0] - x) * (c[1] - y) - (b[1] - y) * (c[0] - x)) / area;
        const double wb = ((c[0] - x) * (a[1] - y) - (c[1] - y) * (a[0] - x)) / area;
        const double wc = 1.0 - wa - wb;
        if (wa * std::abs(area) < tol || wb * std::abs(area) < tol || wc * std::abs(area) < tol) continue;
        r.height[std::size_t(y) * W + x] = wa * a[2] + wb * b[2] + wc * c[2];
      }
  }
  return r;
}

double ground_height(const pm::Heightfield& hf, double x, double y) { return pm::bilinear_height(hf, x, y); }

pm::GroundScale random_ground_scale(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> U(0.0, 1.0);
  const double s1 = 0.8 + 0.45 * U(rng), s2 = 0.8 + 0.45 * U(rng), a = U(rng) * std::numbers::pi;
  const double ca = std::cos(a), sa = std::sin(a);
  return {s1 * ca * ca + s2 * sa * sa, (s1 - s2) * ca * sa, s1 * sa * sa + s2 * ca * ca};
}

pm::Camera random_pose(const pm::Heightfield& hf, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> U(0.0, 1.0);
  const double w = hf.width() - 1, h = hf.height() - 1;
  const double col = (U(rng) * 1.5 - 0.25) * w, row = (U(rng) * 1.5 - 0.25) * h;
  const auto [x, y] = hf.transform.to_world(col, row);
  const double extent = std::max(w * hf.transform.spacing_x(), h * hf.transform.spacing_y());
  pm::Camera c;
  c.x = x, c.y = y;
  c.z = ground_height(hf, x, y) + 2.0 * std::pow(extent, U(rng));  // 2 m .. 2 x extent
  c.yaw_deg = U(rng) * 360.0;
  c.pitch_deg = -90.0 + U(rng) * 105.0;
  c.fovy_deg = 30.0 + U(rng) * 60.0;
  if (U(rng) < 0.5) c.width_px = 640, c.height_px = 480;
  c.near_m = 1.0;
  c.far_m = 10.0 * extent + 1e4;
  return c;
}

std::vector<pm::Camera> scripted_flight(const pm::Heightfield& hf, int frames, double height_m,
                                        double pitch_deg, double laps) {
  std::vector<pm::Camera> out;
  const double w = hf.width() - 1, h = hf.height() - 1;
  for (int k = 0; k < frames; ++k) {
    const double a = 2.0 * std::numbers::pi * laps * k / frames;
    const double col = w * (0.5 + 0.32 * std::cos(a)), row = h * (0.5 + 0.28 * std::sin(a));
    const double col2 = w * (0.5 + 0.32 * std::cos(a + 0.01)), row2 = h * (0.5 + 0.28 * std::sin(a + 0.01));
    const auto [x, y] = hf.transform.to_world(col, row);
    const auto [x2, y2] = hf.transform.to_world(col2, row2);
    pm::Camera c;
    c.x = x, c.y = y;
    c.yaw_deg = std::atan2(x2 - x, y2 - y) * 180.0 / std::numbers::pi;
    c.pitch_deg = pitch_deg;
    // Clear the ground under the camera and a little ahead of it.
    double ground = ground_height(hf, x, y);
    for (double d : {50.0, 100.0, 200.0})
      ground = std::max(ground, ground_height(hf, x + d * std::sin(c.yaw_deg * std::numbers::pi / 180),
                                              y + d * std::cos(c.yaw_deg * std::numbers::pi / 180)));
    c.z = ground + height_m;
    c.far_m = 1e6;
    out.push_back(c);
  }
  return out;
}

std::optional<pm::Heightfield> read_hgt_crop(const std::string& name, int col0, int row0, int size) {
  const std::string path = std::string(TERRALOD_DATA_DIR) + "/" + name;
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  constexpr int N = 1201;
  std::vector<unsigned char> raw(std::size_t(N) * N * 2);
  if (!in.read(reinterpret_cast<char*>(raw.data()), std::streamsize(raw.size()))) return std::nullopt;
  pm::Heightfield hf(size, size);
  for (int r = 0; r < size; ++r)
    for (int c = 0; c < size; ++c) {
      const std::size_t i = (std::size_t(row0 + r) * N + (col0 + c)) * 2;
      hf.at(c, r) = double(std::int16_t(std::uint16_t(raw[i] << 8 | raw[i + 1])));
    }
  const double dy = 6371000.0 * std::numbers::pi / 180.0 / 1200.0;
  const double dx = dy * std::cos(44.5 * std::numbers::pi / 180.0);
  hf.transform = pm::GridTransform::north_up(0.0, 0.0, dx, dy);
  hf.source = path;
  return hf;
}

}  // namespace terralod::test
