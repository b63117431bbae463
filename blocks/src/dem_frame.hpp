// Private to terralod::blocks: the world frame of a DEM read by read_dem, as DemOptions::crs asks
// ("native", "auto" or a CRS): the warp to a projected CRS and the frame's worst scale error.
#pragma once

#include <string>

#include "terralod/pm/heightfield.hpp"

namespace terralod::blocks::detail {

/// `hf`, read in its native frame (dem_reader.cpp), in the frame `crs` asks for (see
/// DemOptions::crs); its hf.frame gains the frame's worst scale error when it has a CRS.
/// Throws DemError naming `path` for a CRS GDAL does not know, a geographic target CRS, a DEM
/// without a CRS to warp from, or a warp GDAL cannot do.
pm::Heightfield apply_frame(const std::string& path, pm::Heightfield hf, const std::string& crs);

}  // namespace terralod::blocks::detail
