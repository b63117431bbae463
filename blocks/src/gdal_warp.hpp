// Private to terralod::blocks: one GDAL warp of a height grid from one CRS to another (bilinear,
// exact coordinate transformations, heights as they are), for the exporters' longitude/latitude
// grids (export/geo_grid.cpp; the DEM reader's frames warp through their own code, dem_frame.cpp).
#pragma once

#include <array>
#include <string>
#include <vector>

namespace terralod::blocks::detail {

/// A north-up or rotated height grid in GDAL's conventions.
struct WarpGrid {
  int width = 0, height = 0;
  std::array<double, 6> gt{};  ///< GDAL geotransform: pixel corners, X = gt0 + col gt1 + row gt2, ...
  std::vector<double> z;       ///< row-major heights, NaN where there is no terrain
};

/// `src` (in CRS src_wkt) warped to CRS dst_wkt with bilinear resampling and exact (not
/// approximated) coordinate transformations, on all cores (GDAL's NUM_THREADS=ALL_CPUS). `target`: the output
/// grid (its width, height and gt; its z is ignored), or nullptr to let GDAL choose a grid covering the
/// source (GDALSuggestedWarpOutput). Output cells outside the source, or whose bilinear neighbourhood holds
/// only NaN, are NaN. On failure returns an empty grid and sets `error` to GDAL's reason. Memory: the source
/// and output grids as doubles, plus GDAL's working buffers.
WarpGrid warp_grid(const WarpGrid& src, const std::string& src_wkt, const std::string& dst_wkt,
                   const WarpGrid* target, std::string& error);

}  // namespace terralod::blocks::detail
