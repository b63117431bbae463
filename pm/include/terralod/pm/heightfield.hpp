// Heightfield: a regular grid of height samples with its affine map to a metric world frame.
//
// Usage:
//   terralod::pm::Heightfield hf(/*width=*/3, /*height=*/2);
//   hf.at(/*col=*/1, /*row=*/0) = 12.5;                 // metres
//   hf.transform = terralod::pm::GridTransform::north_up(/*x0=*/0, /*y0=*/90, /*dx=*/30, /*dy=*/30);
//   glm-free: auto [x, y] = hf.transform.to_world(1.0, 0.0);  // (30, 90)
//
// Contract:
//   - Samples are row-major: index = row * width + col. Row 0 is the first row of the source
//     file (the northern edge for north-up rasters), column 0 its western edge.
//   - Heights are metres, finite wherever valid(col,row) is true. Invalid samples (voids that
//     were kept as holes) hold 0 and must not be read as terrain.
//   - World frame: x east, y north, metres. GridTransform maps (col,row) to (x,y) affinely:
//         x = x0 + col * xc + row * xr
//         y = y0 + col * yc + row * yr
//     For a north-up raster xc = dx, yr = -dy, xr = yc = 0, and (x0,y0) is the centre of the
//     first sample. Geographic (degree) DEMs are mapped by the readers to a local metric frame
//     (see blocks/dem_reader.hpp), so every Heightfield is metric.
//   - Memory: 8 bytes per sample, plus 1 byte per sample when a void mask is kept.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace terralod::pm {

/// Affine map from grid (col,row) to world (x east, y north), metres.
struct GridTransform {
  double x0 = 0.0, xc = 1.0, xr = 0.0;
  double y0 = 0.0, yc = 0.0, yr = 1.0;

  /// North-up raster: first sample centre at (x0, y0), spacing dx east and dy south per row.
  static GridTransform north_up(double x0, double y0, double dx, double dy) {
    return GridTransform{x0, dx, 0.0, y0, 0.0, -dy};
  }
  /// Identity: world = (col, row). Used for sample units.
  static GridTransform identity() { return GridTransform{}; }

  std::pair<double, double> to_world(double col, double row) const {
    return {x0 + col * xc + row * xr, y0 + col * yc + row * yr};
  }
  /// Determinant of the linear part; negative for north-up rasters (row grows southwards).
  double determinant() const { return xc * yr - xr * yc; }
  /// Length in metres of one step along a column (dx) and along a row (dy).
  double spacing_x() const { return std::hypot(xc, yc); }
  double spacing_y() const { return std::hypot(xr, yr); }
  bool operator==(const GridTransform&) const = default;
};

/// How voids (nodata, NaN, SRTM -32768) were handled when the heightfield was made.
struct VoidReport {
  std::size_t voids = 0;   ///< samples that were void in the source
  std::size_t filled = 0;  ///< of those, filled from neighbours (the rest are holes)
};

class Heightfield {
 public:
  Heightfield() = default;
  /// A width x height grid of zeros, all valid. Both sizes must be >= 1.
  Heightfield(int width, int height) : width_(width), height_(height), z_(std::size_t(width) * height, 0.0) {}

  int width() const { return width_; }
  int height() const { return height_; }
  std::size_t size() const { return z_.size(); }

  double& at(int col, int row) { return z_[std::size_t(row) * width_ + col]; }
  double at(int col, int row) const { return z_[std::size_t(row) * width_ + col]; }
  double operator[](std::size_t i) const { return z_[i]; }
  double& operator[](std::size_t i) { return z_[i]; }
  const std::vector<double>& samples() const { return z_; }
  std::vector<double>& samples() { return z_; }

  /// True when the sample is terrain (not a hole). Always true without a void mask.
  bool valid(int col, int row) const { return mask_.empty() || mask_[std::size_t(row) * width_ + col] != 0; }
  bool valid(std::size_t i) const { return mask_.empty() || mask_[i] != 0; }
  bool has_holes() const { return !mask_.empty(); }
  /// 1 = valid, 0 = hole; empty when every sample is valid. Size must be size() when set.
  const std::vector<std::uint8_t>& mask() const { return mask_; }
  void set_mask(std::vector<std::uint8_t> mask) { mask_ = std::move(mask); }

  GridTransform transform;
  VoidReport voids;
  std::string crs_wkt;  ///< coordinate reference system of the source, WKT; empty if unknown
  /// Where the samples lie in crs_wkt: (col,row) of sample centres -> CRS coordinates (degrees
  /// of longitude and latitude for a geographic CRS, the CRS's own linear unit for a projected
  /// one). Empty when the source has no CRS (then the world frame is all there is).
  std::optional<GridTransform> crs_transform;
  /// The heights' vertical datum as the source states it ("EGM96" for SRTM .hgt, the vertical
  /// CRS of a compound CRS, e.g. "EGM96 height", "WGS 84 ellipsoidal height" for a 3D CRS such as
  /// EPSG:4979); empty when the source does not say.
  std::string vertical_datum;
  std::string source;  ///< file the samples came from, or a description of the generator
  std::string frame;   ///< how the world frame was made, e.g. "local equirectangular from lon/lat"

 private:
  int width_ = 0, height_ = 0;
  std::vector<double> z_;
  std::vector<std::uint8_t> mask_;
};

}  // namespace terralod::pm
