// Private to terralod::blocks: the "auto" frame of a geographic DEM (dem_auto_frame.cpp), which
// the frames' warp (dem_frame.cpp) reaches, and the two helpers both write frame descriptions with.
#pragma once

#include <ogr_spatialref.h>

#include <cstdio>
#include <string>

#include "terralod/pm/heightfield.hpp"

namespace terralod::blocks {
class DemSource;
}

namespace terralod::blocks::detail {

/// The frame "auto" gives a geographic DEM (see the top of this file): its CRS (on the source's
/// datum), the factor k0 from CRS metres to the world frame, and the description that starts
/// the frame's text.
struct AutoFrame {
  OGRSpatialReference crs;
  double k0 = 1.0;
  std::string description;
  /// Its balanced scale error where it was measured (0.01: every scale within 1 +- 1 %).
  double error = 0.0;
};

/// The balanced scale error beyond which no flat frame represents a DEM: its largest scale three
/// times its smallest, an extent that reaches about 130 degrees from its centre (a hemisphere's
/// azimuthal frame is within +-22 %). A global DEM's azimuthal frame had k0 = 1.1e-5 and turned
/// 720 x 360 samples into 2 x 723; "auto" keeps such a DEM in its native grid instead
/// (warped_source), whose distances the runtime's view corrects about the camera.
constexpr double kFlatFrameLimit = 0.5;

/// Chooses the "auto" frame of a geographic DEM (see dem_auto_frame.cpp); DemError naming `path`
/// when GDAL can make none of its projections.
AutoFrame auto_frame(const std::string& path, const OGRSpatialReference& source, const pm::GridTransform& st,
                     int w, int h, const DemSource& native);

/// printf of one number.
inline std::string format(const char* fmt, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt, v);
  return buf;
}

/// A CRS's name as frame descriptions give it.
inline std::string name_of(const OGRSpatialReference& srs) {
  const char* name = srs.GetName();
  return name != nullptr ? name : "unnamed CRS";
}

}  // namespace terralod::blocks::detail
