#include "world_placement.hpp"

#include <cmath>
#include <limits>
#include <tuple>

#include "gdal_support.hpp"
#include "terralod/blocks/geo_grid.hpp"

namespace terralod::blocks::detail {

std::string crs_name(const OGRSpatialReference& srs) {
  const char* n = srs.GetName();
  return n != nullptr ? n : "unnamed CRS";
}

std::array<double, 4> empty_sample_box() {
  constexpr double inf = std::numeric_limits<double>::infinity();
  return {inf, inf, -inf, -inf};
}

WorldPlacement::WorldPlacement(const BlockDatabase& db, const OGRSpatialReference& source,
                               const std::string& input)
    : info_(db.info()) {
  const std::optional<Georeference> geo = db.georeference();
  if (info_.crs_wkt.empty() || !geo)
    throw GeoError(
        input + ": the terrain " + db.path() +
        (info_.crs_wkt.empty() ? " has no CRS" : " has no georeference (built by an older terralod)") +
        ", so nothing can be placed on it by its coordinates; build it from a georeferenced DEM");
  OGRSpatialReference target;
  if (target.importFromWkt(info_.crs_wkt.c_str()) != OGRERR_NONE)
    throw DatabaseError(db.path(), "the terrain's CRS is not readable WKT");
  target.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  OGRSpatialReference src(source);
  src.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  CPLErrorReset();
  ct_.reset(OGRCreateCoordinateTransformation(&src, &target));
  if (!ct_)
    throw GeoError(input + ": no transformation from its CRS '" + crs_name(src) + "' to the terrain's CRS '" +
                   crs_name(target) + "' (" + gdal_message("PROJ found none") + ")");
  crs_ = geo->crs_transform;
  det_ = crs_.xc * crs_.yr - crs_.xr * crs_.yc;
  if (!(std::isfinite(det_) && det_ != 0.0))
    throw DatabaseError(db.path(), "the georeference is not invertible");
}

bool WorldPlacement::place(std::span<double> x, std::span<double> y, std::array<double, 4>& samples) {
  ok_.assign(x.size(), 0);
  if (!x.empty() && !ct_->Transform(int(x.size()), x.data(), y.data(), nullptr, ok_.data())) return false;
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (!ok_[i]) return false;
    const double dx = x[i] - crs_.x0, dy = y[i] - crs_.y0;
    const double col = (crs_.yr * dx - crs_.xr * dy) / det_;
    const double row = (crs_.xc * dy - crs_.yc * dx) / det_;
    std::tie(x[i], y[i]) = info_.transform.to_world(col, row);
    if (!std::isfinite(x[i]) || !std::isfinite(y[i])) return false;
    samples = {std::min(samples[0], col), std::min(samples[1], row), std::max(samples[2], col),
               std::max(samples[3], row)};
  }
  return true;
}

}  // namespace terralod::blocks::detail
