// A DEM's samples read window by window, so that a build never has to hold the whole raster:
// the one way the block-database build (tree_builder.hpp) reads its input.
//
// Usage:
//   #include <terralod/blocks/dem_source.hpp>
//   namespace tb = terralod::blocks;
//   auto src = tb::open_dem_source("mosaic.vrt");           // windowed when the frame allows it
//   const tb::DemGrid& g = src->grid();                      // g.width x g.height samples
//   pm::Heightfield b = src->read({0, 0, 256, 256});          // one block, voids filled
//
//   pm::Heightfield hf = tb::read_dem("N44W072.hgt");
//   auto mem = tb::heightfield_source(hf);                   // the same interface over memory
//
// Contract:
//   read(window)  the window's samples exactly as block_heightfield(read_dem(path, options), window)
//                 gives them (partition.hpp): the same bits, a mask only when a sample of the window
//                 is a hole, the transform's origin at the window's first sample computed from the
//                 grid's transform (so a block's world coordinates do not depend on how it was read),
//                 crs_wkt, source and frame copied from the grid. window: inclusive, inside the grid.
//                 Thread-safe: workers call it concurrently.
//   samples_crc   CRC-32 (pm::crc32_of) of the grid's samples as doubles in row-major order, then of
//                 its mask bytes when the grid has a hole: what the database's build parameters
//                 record so that a resumed build checks it reads the same terrain.
//   in_memory     true when the whole grid is held (heightfield_source, or an input read whole,
//                 such as a heightmap image); false when read() reads the file each time.
//   Errors: reading a file throws DemError naming it.
#pragma once

#include <memory>
#include <string>

#include "terralod/blocks/dem_grid.hpp"
#include "terralod/blocks/dem_reader.hpp"

namespace terralod::blocks {

/// The DEM at `path` as read_dem(path, options) reads it, windowed when that is possible: GDAL
/// rasters (GeoTIFF, VRT mosaics such as DemInputs makes, ...) and SRTM .hgt tiles, in any
/// frame. A frame that warps (a named CRS, even the DEM's own; "auto" for a geographic CRS) reads,
/// for each window, the native window under it (dem_frame.hpp's warped_source, which read_dem
/// warps with too), its grid() measured when opening. Inputs that can only be read from their
/// first row on (heightmap images, a .tif without georeference read as Format::Auto, ASCII grids)
/// are decoded once, when opening, into an unnamed temporary file in TMPDIR (4 bytes a sample
/// where a float holds every value, else 8), and windows are read from it. in_memory() is false
/// for every file; heightfield_source's sources hold their grid.
/// Windowed: read() reads its window (grown while a void region meeting it is cut by its edge,
/// then cut back) from the file each time, except the values of filled void regions of 1,024
/// samples or more, which it keeps (DemOptions::filled_void_cache_bytes, 256 MiB by default; least
/// recently used out first) for the later reads that meet them, and regions wider than 64 x 64
/// samples, which it fills one read at a time, so that readers meeting a gap together solve it
/// once (DemSource::void_fill_work counts what was solved and reused); grid() is read from the header when
/// opening, plus, for a grid with a CRS, the valid samples at read_dem's scale-error points (a 33 x 33
/// lattice and the ends of every row, found by reading the edge columns). GDAL's block cache is capped to 64
/// MiB while a windowed GDAL source is open, unless the process set GDAL_CACHEMAX (environment or config
/// option). samples_crc streams bands of rows through read(), one pass. Unlike read_dem, a windowed source
/// has no 2^30-sample limit, and does not check when opening that the grid has a valid sample. DemError as
/// read_dem; read() throws DemError naming the file when it was removed or truncated since it was opened,
/// std::invalid_argument for a window outside the grid.
std::unique_ptr<DemSource> open_dem_source(const std::string& path, const DemOptions& options = {});

}  // namespace terralod::blocks
