// Private to terralod::blocks: one GDAL warp of a height grid from one CRS to another (bilinear,
// exact coordinate transformations, heights as they are), for the exporters' longitude/latitude
// grids (export/geo_grid.cpp; the DEM reader's frames warp through their own code, dem_frame.cpp).
// The source is read window by window (a block database's terrain need not be held whole) and
// the warp writes straight into the returned grid.
#pragma once

#include <array>
#include <functional>
#include <string>
#include <vector>

namespace terralod::blocks::detail {

/// A height grid in GDAL's conventions (the warp's output: north-up).
struct WarpGrid {
  int width = 0, height = 0;
  std::array<double, 6> gt{};  ///< GDAL geotransform: pixel corners, X = gt0 + col gt1 + row gt2, ...
  std::vector<float> z;        ///< row-major heights, NaN where there is no terrain
};

/// A height grid read by windows: read(col0, row0, cols, rows, out) fills out[r * cols + c] with
/// the height of sample (col0 + c, row0 + r), NaN where there is no terrain; it may throw (the
/// warp then stops, and warp_grid throws the reader's exception). Called from one thread at a time.
struct WarpSource {
  int width = 0, height = 0;
  std::array<double, 6> gt{};  ///< as WarpGrid::gt
  std::function<void(int col0, int row0, int cols, int rows, double* out)> read;
  int chunk_mib = 8;  ///< GDAL's chunks of the warp (-wm): memory against the chunks' overhead
};

/// `src` (in CRS src_wkt) warped to CRS dst_wkt on the grid gdalwarp chooses for it (covering the
/// source at about its resolution) with bilinear resampling and exact (not approximated)
/// coordinate transformations, on all cores (GDAL's NUM_THREADS=ALL_CPUS). The output does not
/// depend on the chunks: where it is coarser than the source, GDAL's kernel is widened by the
/// whole grid's ratio of output to source samples in every chunk. Output cells outside
/// the source, or whose nearest source sample is NaN, are NaN (a NaN neighbour is left out of
/// the bilinear weights). When GDAL fails, returns
/// an empty grid and sets `error` to GDAL's reason; what src.read throws is thrown. Memory: the
/// output grid as floats, GDAL's chunks of the warp (source windows and output, chunk_mib each,
/// two at once) and what `src.read` holds; the source is read only where the output needs it.
/// With `layout` (its width, height and gt; z unused) the output is that grid instead, and the
/// kernel is never widened (XSCALE = YSCALE = 1): the caller lays it out at least as fine as the
/// source everywhere (geo_grid.cpp's layouts).
WarpGrid warp_grid(const WarpSource& src, const std::string& src_wkt, const std::string& dst_wkt,
                   std::string& error, const WarpGrid* layout = nullptr);

}  // namespace terralod::blocks::detail
