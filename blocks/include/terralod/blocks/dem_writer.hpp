// DEM writers: a heightfield as a GeoTIFF, a GeoTIFF written strip by strip, and the large test
// terrains of `terralod testdem` (a fractal terrain of any size; a mirror mosaic of a real DEM),
// streamed to disk so that neither is ever held in memory whole.
//
// Usage:
//   namespace tb = terralod::blocks;
//   tb::write_geotiff(hf, "small.tif");                              // one heightfield
//
//   tb::GeoTiffWriter w("big.tif", width, height, transform, crs_wkt);
//   w.write_rows(row0, rows, heights);   // rows x width floats, NaN = void; rows in any order
//   w.commit();                          // closes and renames onto big.tif
//
//   tb::write_fractal_dem(pm::FractalField({.width = 32769, .height = 32769}), "big.tif", 2, progress);
//   tb::MosaicReport m = tb::write_mirror_mosaic("N44W072.hgt", 8, 8, "mosaic/", progress);
//   // mosaic/mosaic.vrt over mosaic/tile_<row>_<col>.tif
//
// Contract:
//   - GeoTIFFs are single-band Float32, tiled 256 x 256, deflate, BigTIFF when needed; the
//     geotransform is the GridTransform's shifted to pixel corners (sample centres at integer
//     (col, row)); the CRS is written when crs_wkt is not empty, as a compound CRS with the
//     heights' vertical datum when one is named and crs_wkt has none (names the exporters read
//     as EGM96 or EGM2008 as their EPSG vertical CRSs 5773 and 3855, read back as "EGM96 height"
//     and "EGM2008 height"; any other name as a vertical CRS of that name); voids are NaN
//     (nodata). Heights
//     round to float: exact for whole metres and for 1/16 m below 2^19 m.
//   - Everything is written to "<path>.tmp.tif" and renamed onto path by commit(); a writer
//     destroyed without commit() removes its temporary, so no half-written file is left under
//     the final name.
//   - write_mirror_mosaic: tile (i, j) (column i from the west, row j from the north) is the
//     source mirrored left-right when i is odd and top-bottom when j is odd, placed so that
//     neighbouring tiles share their edge row or column (the samples on it are equal on both
//     sides): the mosaic is continuous across every tile border, voids included, and spans
//     tiles_x x (width - 1) + 1 by tiles_y x (height - 1) + 1 samples in the source's CRS and
//     spacing. The source is placed in its own CRS units (degrees for an .hgt), so a mosaic of
//     N44W072.hgt spans 44..52 N, 72..64 W at 8 x 8. The VRT (GDALBuildVRT) lists the tiles.
//   - Memory: one strip of rows per thread (fractal), the source plus one tile (mosaic).
//   - Errors: DemError naming the file (cannot create, write or rename; a source without a
//     geotransform for the mosaic); std::invalid_argument for sizes below 1.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "terralod/blocks/dem_reader.hpp"
#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace terralod::blocks {

class GeoTiffWriter {
 public:
  GeoTiffWriter(const std::string& path, std::int64_t width, std::int64_t height,
                const pm::GridTransform& transform, const std::string& crs_wkt = "",
                const std::string& vertical_datum = "");
  ~GeoTiffWriter();
  GeoTiffWriter(const GeoTiffWriter&) = delete;
  GeoTiffWriter& operator=(const GeoTiffWriter&) = delete;
  /// Rows row0 .. row0 + rows - 1, `rows` x width floats, row-major. Not thread-safe.
  void write_rows(std::int64_t row0, std::int64_t rows, const float* heights);
  void commit();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Writes hf as a GeoTIFF (see the contract): with hf.crs_transform, in its CRS (hf.crs_wkt) with
/// that transform and hf.vertical_datum, so read_dem gives back the same frame and datum;
/// without, hf.transform and no CRS.
void write_geotiff(const pm::Heightfield& hf, const std::string& path);

/// Writes every sample of `field` to `path` in strips of 256 rows computed by `threads` threads
/// (0 = every core). progress(fraction) after each strip. Metres, no CRS (as `terralod generate`).
void write_fractal_dem(const pm::FractalField& field, const std::string& path, int threads = 0,
                       const std::function<void(double)>& progress = {});

struct MosaicReport {
  std::string vrt;                     ///< the mosaic, DIR/mosaic.vrt
  std::int64_t width = 0, height = 0;  ///< samples
  int tiles = 0;
};

/// The mirror mosaic of `source` (any DEM read_dem reads, with a geotransform), tiles_x x
/// tiles_y tiles, written into `out_dir` (created). progress(fraction) after each tile.
MosaicReport write_mirror_mosaic(const std::string& source, int tiles_x, int tiles_y,
                                 const std::string& out_dir,
                                 const std::function<void(double)>& progress = {});

}  // namespace terralod::blocks
