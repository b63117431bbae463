// WGS 84 geodesy for the exporters: geodetic <-> Earth-centred Earth-fixed (ECEF) coordinates,
// the surface normal, bounding spheres, and the horizon-culling point CesiumJS uses to skip
// tiles behind the Earth.
//
// Usage:
//   namespace pm = terralod::pm;
//   pm::Ecef p = pm::ecef_from_geodetic({-71.5, 44.5, 1200.0});   // degrees, degrees, metres
//   pm::Geodetic g = pm::geodetic_from_ecef(p);                     // back, to < 1e-9 m
//   pm::EcefSphere s = pm::bounding_sphere(points);                     // contains every point
//   pm::Ecef h = pm::horizon_occlusion_point(points, s.center);     // ellipsoid-scaled frame
//
// Contract:
//   - Geodetic: longitude and latitude in degrees (east and north positive), height in metres
//     above the WGS 84 ellipsoid (a = 6378137 m, f = 1 / 298.257223563). Ecef in metres.
//   - geodetic_from_ecef: Bowring's iteration to machine precision (heights to ~1e-9 m) for any
//     point farther than 1 km from the Earth's centre.
//   - bounding_sphere: the centre of the points' axis-aligned box and the largest distance to
//     it (contains every point; within sqrt(3) of the smallest sphere). Empty input: radius 0.
//   - horizon_occlusion_point(points, direction): CesiumJS's
//     EllipsoidalOccluder.computeHorizonCullingPoint. In the ellipsoid-scaled frame (ECEF
//     divided componentwise by the radii (a, a, b)), the point along the scaled `direction`
//     from which every point is visible (so when it is below the horizon, all of them are).
//     Points below the ellipsoid are treated as on it (Cesium's "possibly under ellipsoid"
//     variant lifts them the same way). Returns the scaled point; when no such point exists (the
//     points span more than the hemisphere around `direction`) its x is NaN, as Cesium returns
//     undefined.
#pragma once

#include <array>
#include <span>

namespace terralod::pm {

struct Geodetic {
  double lon_deg = 0, lat_deg = 0, height = 0;
};
using Ecef = std::array<double, 3>;

struct EcefSphere {
  Ecef center{};
  double radius = 0;
};

inline constexpr double kWgs84A = 6378137.0;
inline constexpr double kWgs84F = 1.0 / 298.257223563;
inline constexpr double kWgs84B = kWgs84A * (1.0 - kWgs84F);

Ecef ecef_from_geodetic(const Geodetic& g);
/// The same on the ellipsoid of semi-major axis a and squared eccentricity e2 (a CRS's own).
Ecef ecef_from_geodetic(const Geodetic& g, double a, double e2);
Geodetic geodetic_from_ecef(const Ecef& p);
/// The outward unit normal of the ellipsoid at (lon, lat).
Ecef geodetic_surface_normal(double lon_deg, double lat_deg);

EcefSphere bounding_sphere(std::span<const Ecef> points);
Ecef horizon_occlusion_point(std::span<const Ecef> points, const Ecef& direction);

}  // namespace terralod::pm
