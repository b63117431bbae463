// A georeferenced image (an orthophoto, a scanned map: any raster GDAL reads with a
// geotransform and a CRS) warped into a terrain's world frame, for a texture layer.
//
// Usage:
//   const auto w = tb::warp_image_to_terrain("ortho.tif", db, "db.ortho.tif", progress);
//   if (w) { /* w->path is an RGBA GeoTIFF covering the world box w->minx..maxy */ }
//
// Contract:
//   warp_image_to_terrain(image, db, out, progress)
//     image    any raster GDAL reads. Without a geotransform or a CRS it is not georeferenced:
//              nullopt, nothing written (texture layers then stretch it over the terrain).
//              Bands: grey, grey + alpha, RGB, RGBA or a colour table (expanded to RGB); a band
//              is alpha when its colour interpretation says so, and of more bands than that
//              (RGB + near infrared) the first three others are RGB. Bands of any depth:
//              `stretch` (image_stretch.hpp) turns 16-bit, 32-bit and floating-point colour bands
//              into bytes (by default each band's 2 % to 98 % cut, over its valid pixels); their
//              nodata, which bytes cannot keep, becomes the alpha band.
//     db       a database whose terrain has a CRS and a georeference (DatabaseInfo::crs_wkt,
//              BlockDatabase::georeference) and north-up transforms (no rotation), so that a
//              box of its CRS is a box of its world frame.
//     out      written: a tiled, deflated RGBA GeoTIFF in the terrain's CRS (bilinear, exact
//              coordinate transformations), over the part of the terrain's footprint that the
//              image covers, at about the image's own resolution; alpha 0 where the image is
//              not. Written beside its final name and renamed into place: never half-written.
//     returns  the world extent of out's pixels (metres; minx < maxx, miny < maxy) and its size.
//     progress called with the fraction done (0..1; a stretch's histogram pass is the first
//              0.3), from the calling thread; may be empty.
//     errors   ImageWarpError "<image>: <problem>": a band that cannot be read, no overlap with the terrain,
//     a
//              terrain without CRS or georeference, a rotated frame, GDAL's reason when it cannot
//              transform or write.
//   Cost: one GDAL warp of the overlapping part (about the image's pixel count), on all cores;
//   a cut stretch reads each colour band once before (twice for 32-bit and floating point, whose
//   range is measured first), a band of rows at a time. GDAL's block cache is capped to 64 MiB
//   meanwhile (unless GDAL_CACHEMAX is set), so memory does not grow with the image.
#pragma once

#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/image_stretch.hpp"

namespace terralod::blocks {

/// Error of warp_image_to_terrain; what() is "<image>: <problem>".
class ImageWarpError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Where a warped image lies (see the header comment).
struct WorldImage {
  double minx = 0, miny = 0, maxx = 0, maxy = 0;  ///< world metres, the pixels' outer edges
  int width = 0, height = 0;                      ///< pixels of the written image
  /// The ranges of the image's values drawn as 0..255 in R, G and B; empty when its 8-bit
  /// bands were taken as they are.
  std::vector<BandRange> stretched;
};

/// See the header comment.
std::optional<WorldImage> warp_image_to_terrain(const std::string& image, const BlockDatabase& db,
                                                const std::string& out,
                                                const std::function<void(double)>& progress = {},
                                                const StretchOptions& stretch = {});

}  // namespace terralod::blocks
