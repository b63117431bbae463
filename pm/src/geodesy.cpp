// WGS 84 geodesy (see geodesy.hpp).
#include "terralod/pm/geodesy.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace terralod::pm {
namespace {

constexpr double kE2 = kWgs84F * (2.0 - kWgs84F);  // first eccentricity squared
constexpr double kDeg = std::numbers::pi / 180.0;

double dot(const Ecef& a, const Ecef& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
double norm(const Ecef& a) { return std::sqrt(dot(a, a)); }
Ecef cross(const Ecef& a, const Ecef& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
Ecef scaled(const Ecef& p) { return {p[0] / kWgs84A, p[1] / kWgs84A, p[2] / kWgs84B}; }

}  // namespace

Ecef ecef_from_geodetic(const Geodetic& g) { return ecef_from_geodetic(g, kWgs84A, kE2); }

Ecef ecef_from_geodetic(const Geodetic& g, double a, double e2) {
  const double lon = g.lon_deg * kDeg, lat = g.lat_deg * kDeg;
  const double s = std::sin(lat), c = std::cos(lat);
  const double n = a / std::sqrt(1.0 - e2 * s * s);
  return {(n + g.height) * c * std::cos(lon), (n + g.height) * c * std::sin(lon),
          (n * (1.0 - e2) + g.height) * s};
}

Geodetic geodetic_from_ecef(const Ecef& p) {
  const double r = std::hypot(p[0], p[1]);
  Geodetic g;
  g.lon_deg = std::atan2(p[1], p[0]) / kDeg;
  // Fixed-point iteration on the latitude (converges to machine precision in a few steps for
  // points near the surface; 10 steps is ample).
  double lat = std::atan2(p[2], r * (1.0 - kE2));
  double n = kWgs84A;
  for (int i = 0; i < 10; ++i) {
    const double s = std::sin(lat);
    n = kWgs84A / std::sqrt(1.0 - kE2 * s * s);
    const double h = r / std::cos(lat) - n;
    lat = std::atan2(p[2], r * (1.0 - kE2 * n / (n + h)));
  }
  const double s = std::sin(lat), c = std::cos(lat);
  n = kWgs84A / std::sqrt(1.0 - kE2 * s * s);
  // Height: the better-conditioned formula for the latitude range.
  g.height = std::abs(c) > 0.5 ? r / c - n : p[2] / s - n * (1.0 - kE2);
  g.lat_deg = lat / kDeg;
  return g;
}

Ecef geodetic_surface_normal(double lon_deg, double lat_deg) {
  const double lon = lon_deg * kDeg, lat = lat_deg * kDeg;
  return {std::cos(lat) * std::cos(lon), std::cos(lat) * std::sin(lon), std::sin(lat)};
}

EcefSphere bounding_sphere(std::span<const Ecef> points) {
  EcefSphere s;
  if (points.empty()) return s;
  Ecef lo = points[0], hi = points[0];
  for (const Ecef& p : points)
    for (int k = 0; k < 3; ++k) {
      lo[std::size_t(k)] = std::min(lo[std::size_t(k)], p[std::size_t(k)]);
      hi[std::size_t(k)] = std::max(hi[std::size_t(k)], p[std::size_t(k)]);
    }
  for (int k = 0; k < 3; ++k) s.center[std::size_t(k)] = 0.5 * (lo[std::size_t(k)] + hi[std::size_t(k)]);
  for (const Ecef& p : points)
    s.radius = std::max(s.radius, norm({p[0] - s.center[0], p[1] - s.center[1], p[2] - s.center[2]}));
  return s;
}

Ecef horizon_occlusion_point(std::span<const Ecef> points, const Ecef& direction) {
  // The scaled-space direction of the point (Cesium: computeScaledSpaceDirectionToPoint).
  Ecef d = scaled(direction);
  const double dn = norm(d);
  if (dn == 0) return {0, 0, 0};
  for (double& x : d) x /= dn;
  double magnitude = 0;
  for (const Ecef& p : points) {
    // Cesium's computeMagnitude: the distance along d at which p's tangent cone to the unit
    // sphere (scaled space) passes, with p lifted onto the sphere when it is below it.
    const Ecef q = scaled(p);
    double m2 = dot(q, q);
    double m = std::sqrt(m2);
    if (m == 0) continue;
    const Ecef dir{q[0] / m, q[1] / m, q[2] / m};
    m2 = std::max(1.0, m2);
    m = std::max(1.0, m);
    const double cos_alpha = dot(dir, d);
    const double sin_alpha = norm(cross(dir, d));
    const double cos_beta = 1.0 / m;
    const double sin_beta = std::sqrt(m2 - 1.0) * cos_beta;
    const double denom = cos_alpha * cos_beta - sin_alpha * sin_beta;
    if (denom <= 0) return {std::numeric_limits<double>::quiet_NaN(), 0, 0};  // no such point
    magnitude = std::max(magnitude, 1.0 / denom);
  }
  return {d[0] * magnitude, d[1] * magnitude, d[2] * magnitude};
}

}  // namespace terralod::pm
