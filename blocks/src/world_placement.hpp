// Coordinates of any CRS GDAL knows, moved onto a block database's world frame: source CRS ->
// the database's CRS (OGR, PROJ) -> sample (col, row) through the georeference -> world metres
// through DatabaseInfo::transform. Used by the object layers (object_layers.cpp) and by flight
// tracks (flight_track.cpp), so that a feature and a track point at the same place land on the
// same world point.
//
// Contract:
//   - The constructor throws GeoError "<input>: <problem>" when the database has no CRS or no
//     georeference (an older build), or PROJ has no transformation from `source` to it;
//     DatabaseError when the database's CRS or georeference is unusable.
//   - place() moves points (x[i], y[i]) in place and widens `samples` (cmin, rmin, cmax, rmax) by
//     their sample positions; false (points then partly moved) if any point cannot be
//     transformed. Plain coordinates, so that every concept that places things can call it.
//   - Axis order: traditional GIS order (x = longitude / easting) for both CRSs.
#pragma once

#include <ogr_spatialref.h>

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "terralod/blocks/block_database.hpp"

namespace terralod::blocks::detail {

/// Cmin, rmin, cmax, rmax that any place() widens.
std::array<double, 4> empty_sample_box();

class WorldPlacement {
 public:
  WorldPlacement(const BlockDatabase& db, const OGRSpatialReference& source, const std::string& input);

  bool place(std::span<double> x, std::span<double> y, std::array<double, 4>& samples);

 private:
  DatabaseInfo info_;
  std::unique_ptr<OGRCoordinateTransformation> ct_;
  pm::GridTransform crs_;
  double det_ = 1.0;
  std::vector<int> ok_;
};

/// The name GDAL gives `srs`, else "unnamed CRS".
std::string crs_name(const OGRSpatialReference& srs);

}  // namespace terralod::blocks::detail
