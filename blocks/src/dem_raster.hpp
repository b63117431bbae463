// Private to terralod::blocks: the parts of read_dem (dem_reader.cpp) that the windowed DEM source
// (dem_windows.cpp) calls too, so that both read a file's header, georeference, voids and heights
// the same way: format choice, GDAL band header and windowed sample reads, the .hgt header and
// windowed row reads, and the native world frame; and what read_dem's readers share (Raster).
#pragma once

#include <OpenImageIO/imageio.h>
#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <array>
#include <cmath>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/sample_rect.hpp"
#include "terralod/pm/heightfield.hpp"

namespace terralod::blocks::detail {

/// Heights further than this from the datum are no terrain (the Earth's radius is 6.4e6 m): they
/// are fill values a file does not declare as its nodata, such as -3.4e38 (the least float) in
/// rasters exported without a nodata tag. Every reader takes them as voids, as it does NaN: kept
/// as heights they became a root error of 3.4e38 m and a terrain no view could frame.
constexpr double kMaxHeightMetres = 1e7;

/// Whether `metres` is a height (finite and within kMaxHeightMetres of the datum).
inline bool is_height(double metres) { return std::abs(metres) <= kMaxHeightMetres; }

/// A file's georeferencing, as every reader finds it.
struct Georef {
  enum class Kind { None, Geographic, Metric } kind = Kind::None;
  /// Sample-centre affine map: X = a[0] + col a[1] + row a[2], Y = a[3] + col a[4] + row a[5];
  /// degrees (lon, lat) for Geographic, metres for Metric, unused for None.
  std::array<double, 6> a{};
  /// The same map in the CRS's own units (degrees for geographic CRSs): Heightfield::crs_transform.
  std::array<double, 6> native{};
  std::string crs_wkt;
  std::string vertical_datum;  ///< Heightfield::vertical_datum
  std::string description;     ///< Metric: what the coordinates are; Geographic: the CRS name
};

/// What every reader produces before read_dem's common finishing steps (frame, voids).
struct Raster {
  int width = 0, height = 0;
  std::vector<double> z;  ///< row-major; non-finite = void
  Georef geo;
  std::string height_note;  ///< appended to the frame description when not empty
};

/// DemError naming `path` unless it is an existing regular file.
void require_file(const std::string& path);
/// DemError naming `path` for a grid under 2 x 2 or over 2^30 samples.
void check_dimensions(const std::string& path, long long w, long long h);
/// `v` with 12 significant digits, for frame descriptions.
std::string format_number(double v);

/// A heightmap image (grey, or grey and alpha, 0 marking a void) read through OpenImageIO in bands
/// of rows from the top (dem_heightmap.cpp): the only order PNG decodes in without starting over.
/// DemError naming the path when the file is no such image (under 2 x 2 pixels, or over 2^30 when
/// `limit_size`), or cannot be read.
class HeightmapRows {
 public:
  HeightmapRows(const std::string& path, bool limit_size);
  ~HeightmapRows();
  int width() const;
  int height() const;
  /// Whether every raw value is a float exactly (8- and 16-bit integers, half, float).
  bool exact_in_float() const { return exact_in_float_; }
  /// The next band of whole rows as raw values (NaN where alpha is 0) into `raw`, row-major;
  /// its number of rows, 0 after the last row.
  int next(std::vector<double>& raw);

 private:
  std::string path_;
  std::unique_ptr<OIIO::ImageInput> in_;
  OIIO::TypeDesc type_;  ///< what the pixels are read as: integers in their own type, else double
  bool alpha_ = false, exact_in_float_ = false;
  int band_rows_ = 1, next_row_ = 0;
  std::vector<unsigned char> bytes_;
};

/// The height in metres of a heightmap's raw value: raw * scale + offset (DemOptions'
/// vertical_scale and vertical_offset), NaN for a void or a value that is no height (is_height).
double heightmap_metres(double raw, double scale, double offset);
/// The frame note of a heightmap read with `options` ("" for scale 1, offset 0).
std::string heightmap_note(const DemOptions& options);

/// A heightmap image read whole (HeightmapRows, heightmap_metres), no georeference.
Raster read_heightmap(const std::string& path, const DemOptions& options);

/// An Esri ASCII grid (header keys ncols, nrows, xllcorner|xllcenter, yllcorner|yllcenter,
/// cellsize or dx and dy, NODATA_value; a sidecar .prj gives the CRS) read from the top in bands of
/// rows (dem_ascii_grid.cpp). The header is read at opening. DemError naming the path (and the
/// line) for a malformed grid; over 2^30 values only when `limit_size`.
class AsciiGridRows {
 public:
  AsciiGridRows(const std::string& path, bool limit_size);
  ~AsciiGridRows();
  int width() const { return width_; }
  int height() const { return height_; }
  const Georef& georef() const { return geo_; }
  /// The next band of whole rows in metres (NODATA_value and non-heights NaN) into `z`, row-major;
  /// its number of rows, 0 after the last row. The last band also checks that no value follows.
  int next(std::vector<double>& z);

 private:
  class Tokens;
  std::string path_;
  std::ifstream in_;
  std::unique_ptr<Tokens> tokens_;
  int width_ = 0, height_ = 0, band_rows_ = 1, next_row_ = 0;
  std::optional<double> nodata_;
  Georef geo_;
};

/// An Esri ASCII grid read whole (AsciiGridRows).
Raster read_ascii_grid(const std::string& path);

/// The Raster of every band `rows` (HeightmapRows, AsciiGridRows) gives, each value through
/// `metres`; georeference not set.
template <typename Rows, typename Metres>
Raster read_all_rows(Rows& rows, Metres metres) {
  Raster r;
  r.width = rows.width();
  r.height = rows.height();
  r.z.reserve(std::size_t(r.width) * std::size_t(r.height));
  std::vector<double> band;
  while (rows.next(band) > 0)
    for (double v : band) r.z.push_back(metres(v));
  return r;
}

/// `srs` as WKT ("" when it cannot be exported).
std::string wkt_of(const OGRSpatialReference& srs);
/// geo.kind, a, native and description from a corner-convention geotransform and an optional CRS.
void georeference(Georef& geo, const double gt[6], const OGRSpatialReference* srs);

/// The format read_dem reads `path` as (DemOptions::Format::Auto resolved, never Auto). For Gdal,
/// `ds` is the opened dataset; a .tif/.tiff without georeference read as Auto is a Heightmap.
DemOptions::Format dem_format(const std::string& path, const DemOptions& options, GDALDatasetUniquePtr& ds);

/// `path` opened by GDAL as a read-only raster; DemError naming it when GDAL cannot.
GDALDatasetUniquePtr open_gdal(const std::string& path);

/// std::invalid_argument for an invalid DemOptions value (see read_dem).
void check_options(const DemOptions& options);

/// A single-band GDAL raster's header: what read_gdal applies to every sample it reads.
struct GdalBand {
  int width = 0, height = 0;
  bool has_nodata = false;  ///< a nodata value that is not NaN
  double nodata = 0.0;      ///< compared in the band's type (float for Float32 bands)
  bool nodata_as_float = false;
  bool mask_band = false;            ///< a real mask band: its 0 samples are voids
  int index = 1;                     ///< the band of the heights (1-based)
  int alpha_index = 0;               ///< an alpha band (0: none): its 0 samples are voids
  double factor = 1.0, shift = 0.0;  ///< metres = raw * factor + shift (scale, offset, unit)
  std::string height_note;           ///< appended to the frame description when not empty
  Georef geo;
};

/// How read_dem makes a GDAL band's samples metres: metres = sample * factor + shift, from the
/// band's scale and offset, then its vertical unit. `unit` is the band's as it states it; `known`
/// is false for a unit that is not metres, feet or US survey feet (then taken as metres).
struct HeightScale {
  double factor = 1.0, shift = 0.0;
  std::string unit;
  bool known = true;
  bool metres() const { return factor == 1.0 && shift == 0.0; }
  bool operator==(const HeightScale& o) const { return factor == o.factor && shift == o.shift; }
};
HeightScale height_scale(GDALRasterBand& band);

/// The header of band `index` of `ds` (0: the only band, with an alpha band besides or not), of a
/// real type, at least 2 x 2 samples (at most 2^30 when `limit_size`). DemError naming `path`.
GdalBand gdal_band(const std::string& path, GDALDataset& ds, bool limit_size, int index);

/// The samples of `window` of the band `band` describes into `z` (resized, row-major), in metres, voids
/// (nodata, mask band, NaN, +-inf, beyond kMaxHeightMetres) NaN. DemError naming `path` when
/// GDAL cannot read them.
void read_gdal_window(const std::string& path, GDALDataset& ds, const GdalBand& band, SampleRect window,
                      std::vector<double>& z);

/// An SRTM .hgt tile's header: n x n samples and its georeference (from the name and size).
struct HgtTile {
  int n = 0;
  Georef geo;
};
HgtTile hgt_tile(const std::string& path);

/// The samples of `window` of the n x n tile at `path` into `z`, read row by row from the file;
/// -32768 is NaN. DemError naming `path` when the file is gone, shorter than n x n x 2 bytes or
/// unreadable.
void read_hgt_window(const std::string& path, int n, SampleRect window, std::vector<double>& z);

/// The native world transform of a width x height grid georeferenced by `geo`, and `frame`, the
/// line that says how it was made. DemError naming `path` for a degenerate georeference.
pm::GridTransform world_transform(const std::string& path, int width, int height, const Georef& geo,
                                  const DemOptions& options, std::string& frame);

}  // namespace terralod::blocks::detail
