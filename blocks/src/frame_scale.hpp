// Private to terralod::blocks: the worst scale error of a georeferenced frame (detail::scale_error,
// measured against the CRS's ellipsoid at frame_scale_error's points, dem_grid.hpp) and the
// coordinate helpers it shares with the frames' warp (dem_frame.cpp). Below dem_reader, which it
// never includes; this header includes neither dem_reader.hpp nor dem_grid.hpp (frame_scale.cpp
// defines dem_grid.hpp's frame_scale_error).
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/view.hpp"

class OGRCoordinateTransformation;

namespace terralod::blocks::detail {

struct TransformDeleter {
  void operator()(OGRCoordinateTransformation* t) const;
};
/// An owned GDAL coordinate transformation.
using Transform = std::unique_ptr<OGRCoordinateTransformation, TransformDeleter>;

/// Transforms the points in place; false when any fails.
bool transform(OGRCoordinateTransformation& ct, std::vector<double>& x, std::vector<double>& y);

/// A CRS's geographic CRS (longitude, latitude in degrees, GIS order) and its ellipsoid: the
/// transformations both ways, the semi-major axis a and the squared eccentricity e2. nullopt
/// when GDAL cannot read the WKT or make either transformation. Registers GDAL's drivers.
struct GeographicOf {
  Transform to_geog, to_crs;
  double a = 0, e2 = 0;
};
std::optional<GeographicOf> geographic_of(const std::string& crs_wkt);

/// (col, row) -> (x, y) of an affine map and back.
struct Affine {
  pm::GridTransform t;
  std::pair<double, double> inverse(double x, double y) const {
    const double det = t.xc * t.yr - t.xr * t.yc, dx = x - t.x0, dy = y - t.y0;
    return {(t.yr * dx - t.xr * dy) / det, (t.xc * dy - t.yc * dx) / det};
  }
};

/// The smallest and largest scale of a frame over geographic points (lon, lat in degrees on the
/// ellipsoid of semi-major axis a and squared eccentricity e2): the singular values of the
/// Jacobian of (east, north metres on the ellipsoid) -> frame, by differences over +-0.001 degrees
/// passed through `to_frame` (geographic degrees -> frame metres, in place; false when it fails).
/// Points within 0.1 degree of a pole are skipped ({1, 1} when none is left); nullopt when
/// to_frame fails.
std::optional<std::pair<double, double>> scale_range(
    const std::vector<double>& lon, const std::vector<double>& lat, double a, double e2,
    const std::function<bool(std::vector<double>&, std::vector<double>&)>& to_frame);

/// frame_scale_error of a w x h grid known through `valid` (col, row) and `row_ends` (row -> its
/// first and last valid column, first == w when it has none, last >= first), so that a grid that
/// is not held can be measured at the same points.
std::optional<double> scale_error(const std::string& crs_wkt,
                                  const std::optional<pm::GridTransform>& crs_transform,
                                  const pm::GridTransform& world, int w, int h,
                                  const std::function<bool(int, int)>& valid,
                                  const std::function<std::pair<int, int>(int)>& row_ends);

/// The implementation of GroundScaleMap (ground_scale.hpp, which says what G is).
class GroundFrame {
 public:
  /// nullopt when the frame has no CRS, or GDAL cannot map the CRS to its geographic CRS.
  static std::optional<GroundFrame> open(const std::string& crs_wkt, const pm::GridTransform& crs_transform,
                                         const pm::GridTransform& world);
  /// G at world (x, y); nullopt when the point cannot be transformed (beyond the projection's
  /// domain) or G's scales leave [0.5, 2] (a frame no view can take). Not thread-safe.
  std::optional<pm::GroundScale> at(double x, double y) const;

 private:
  Transform to_geog_;
  Affine crs_, world_;
  double a_ = 0, e2_ = 0;
};

}  // namespace terralod::blocks::detail
