// Private to terralod::blocks: the world frame of a DEM read by read_dem, as DemOptions::crs asks
// ("native", "auto" or a CRS): the warp to a projected CRS and the frame's worst scale error.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <utility>

#include "terralod/pm/heightfield.hpp"

namespace terralod::blocks::detail {

/// `hf`, read in its native frame (dem_reader.cpp), in the frame `crs` asks for (see
/// DemOptions::crs); its hf.frame gains the frame's worst scale error when it has a CRS.
/// Throws DemError naming `path` for a CRS GDAL does not know, a geographic target CRS, a DEM
/// without a CRS to warp from, or a warp GDAL cannot do.
pm::Heightfield apply_frame(const std::string& path, pm::Heightfield hf, const std::string& crs);

/// Whether apply_frame warps a DEM with this CRS (crs_wkt, and a transform to it or not) to the
/// frame `crs` asks for: never for "native"; for "auto" when the CRS is geographic; always for a
/// named CRS (even the DEM's own), which apply_frame warps to or refuses.
bool frame_warps(const std::string& crs_wkt, bool has_crs_transform, const std::string& crs);

/// frame_scale_error (dem_reader.hpp) of a w x h grid known through `valid` (col, row) and
/// `row_ends` (row -> its first and last valid column, first == w when it has none, last >= first),
/// so that a grid that is not held can be measured at the same points.
std::optional<double> scale_error(const std::string& crs_wkt,
                                  const std::optional<pm::GridTransform>& crs_transform,
                                  const pm::GridTransform& world, int w, int h,
                                  const std::function<bool(int, int)>& valid,
                                  const std::function<std::pair<int, int>(int)>& row_ends);

/// What apply_frame appends to a frame for scale error `e` ("" for nullopt); `automatic`: the
/// "auto" frame's warning over 0.1 %.
std::string scale_error_note(std::optional<double> e, bool automatic);

}  // namespace terralod::blocks::detail
