// Reads SRTM .hgt tiles, GDAL rasters, OpenImageIO heightmaps and Esri ASCII grids into metric
// Heightfields, mapping geographic grids to a local equirectangular frame and filling voids; the
// other frames (DemOptions::crs) are dem_frame.cpp's.
#include "terralod/blocks/dem_reader.hpp"

#include <OpenImageIO/imageio.h>
#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <mutex>
#include <numbers>
#include <optional>
#include <sstream>
#include <string_view>
#include <system_error>

#include "dem_frame.hpp"
#include "dem_raster.hpp"
#include "gdal_support.hpp"
#include "terralod/blocks/void_fill.hpp"

namespace terralod::blocks {

namespace {

namespace fs = std::filesystem;
using Format = DemOptions::Format;

/// Mean Earth radius (IUGG), metres: the sphere of the local equirectangular frame.
constexpr double kEarthRadius = 6371008.8;
/// Largest grid read (8 GiB of doubles); guards against absurd sizes in corrupt headers.
constexpr std::size_t kMaxSamples = std::size_t(1) << 30;
constexpr double kDeg = std::numbers::pi / 180.0;

using detail::check_dimensions;
using detail::format_number;
using detail::Georef;
using detail::Raster;
using detail::require_file;

using detail::lower;

// ---------------------------------------------------------------------------------------------
// GDAL plumbing: registration once, errors captured instead of printed.

using detail::gdal_message;
using detail::QuietGdal;
using detail::register_gdal;

// ---------------------------------------------------------------------------------------------
// SRTM .hgt

}  // namespace

namespace detail {

std::string wkt_of(const OGRSpatialReference& srs) {
  char* text = nullptr;
  std::string out;
  if (srs.exportToWkt(&text) == OGRERR_NONE && text != nullptr) out = text;
  CPLFree(text);
  return out;
}

void georeference(Georef& geo, const double gt[6], const OGRSpatialReference* srs) {
  // GDAL's geotransform maps pixel corners; sample centres sit half a pixel in.
  std::array<double, 6> a = {gt[0] + 0.5 * gt[1] + 0.5 * gt[2], gt[1], gt[2],
                             gt[3] + 0.5 * gt[4] + 0.5 * gt[5], gt[4], gt[5]};
  geo.native = a;
  if (const std::string v = srs != nullptr ? detail::vertical_datum_of(*srs) : ""; !v.empty())
    geo.vertical_datum = v;
  if (srs != nullptr && !srs->IsEmpty() && srs->IsGeographic()) {
    const double to_degrees = srs->GetAngularUnits(nullptr) / kDeg;  // radians per unit -> degrees
    for (double& v : a) v *= to_degrees;
    geo.native = a;  // PROJ is given degrees for geographic CRSs
    geo.kind = Georef::Kind::Geographic;
    const char* name = srs->GetName();
    geo.description = name != nullptr ? name : "geographic CRS";
  } else if (srs != nullptr && !srs->IsEmpty()) {
    const double to_metres = srs->GetLinearUnits(nullptr);
    for (double& v : a) v *= to_metres;
    geo.kind = Georef::Kind::Metric;
    const char* name = srs->GetName();
    geo.description = std::string("coordinates of CRS '") + (name != nullptr ? name : "?") +
                      "' in metres (unit factor " + format_number(to_metres) + ")";
  } else {
    geo.kind = Georef::Kind::Metric;
    geo.description = "geotransform coordinates without a CRS, taken as metres";
  }
  geo.a = a;
}

std::string format_number(double v) {
  std::ostringstream s;
  s.precision(12);
  s << v;
  return s.str();
}

void require_file(const std::string& path) {
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (!fs::exists(st)) throw DemError(path, "no such file");
  if (!fs::is_regular_file(st)) throw DemError(path, "not a regular file");
}

void check_dimensions(const std::string& path, long long w, long long h) {
  if (w < 2 || h < 2) {
    throw DemError(path, "grid is " + std::to_string(w) + " x " + std::to_string(h) +
                             "; at least 2 x 2 samples are needed");
  }
  if (double(w) * double(h) > double(kMaxSamples)) {
    throw DemError(path, "grid is " + std::to_string(w) + " x " + std::to_string(h) +
                             "; more than 2^30 samples are not supported");
  }
}

HgtTile hgt_tile(const std::string& path) {
  // South-west corner from the name: [NS]dd[EW]ddd, e.g. N44W072 (case-insensitive).
  const std::string name = fs::path(path).filename().string();
  auto digits = [&](std::size_t from, std::size_t count, int& value) {
    if (name.size() < from + count) return false;
    value = 0;
    for (std::size_t k = from; k < from + count; ++k) {
      if (name[k] < '0' || name[k] > '9') return false;
      value = value * 10 + (name[k] - '0');
    }
    return true;
  };
  int lat = 0, lon = 0;
  const char ns = name.empty() ? '\0' : char(std::toupper((unsigned char)name[0]));
  const char ew = name.size() > 3 ? char(std::toupper((unsigned char)name[3])) : '\0';
  if ((ns != 'N' && ns != 'S') || !digits(1, 2, lat) || (ew != 'E' && ew != 'W') || !digits(4, 3, lon) ||
      (name.size() > 7 && name[7] >= '0' && name[7] <= '9')) {
    throw DemError(path, "file name does not give the tile's south-west corner (expected e.g. N44W072.hgt)");
  }
  if (ns == 'S') lat = -lat;
  if (ew == 'W') lon = -lon;
  if (lat < -90 || lat > 89 || lon < -180 || lon > 179) {
    throw DemError(path, "file name gives an impossible south-west corner (lat " + std::to_string(lat) +
                             ", lon " + std::to_string(lon) + ")");
  }

  require_file(path);
  std::error_code ec;
  const std::uintmax_t bytes = fs::file_size(path, ec);
  if (ec) throw DemError(path, "cannot get the file size: " + ec.message());
  if (bytes == 0) throw DemError(path, "file is empty");
  const auto n = static_cast<std::uintmax_t>(std::llround(std::sqrt(double(bytes) / 2.0)));
  if (bytes % 2 != 0 || n * n * 2 != bytes) {
    throw DemError(path, "file size " + std::to_string(bytes) +
                             " bytes is not that of a square grid of 16-bit samples (n * n * 2 bytes, "
                             "e.g. 2884802 for a 1201 x 1201 SRTM3 tile)");
  }
  check_dimensions(path, (long long)n, (long long)n);

  HgtTile t;
  t.n = int(n);
  const double d = 1.0 / double(n - 1);  // degrees between samples; samples sit on the tile edges
  t.geo.kind = Georef::Kind::Geographic;
  t.geo.a = {double(lon), d, 0.0, double(lat) + 1.0, 0.0, -d};
  t.geo.native = t.geo.a;
  t.geo.vertical_datum = "EGM96";  // SRTM heights are above the EGM96 geoid
  register_gdal();
  QuietGdal quiet;
  OGRSpatialReference wgs84;
  wgs84.SetWellKnownGeogCS("WGS84");
  t.geo.crs_wkt = wkt_of(wgs84);
  t.geo.description = "WGS 84";
  return t;
}

void read_hgt_window(const std::string& path, int n, SampleRect window, std::vector<double>& z) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw DemError(path, "cannot open the file for reading (removed since it was opened?)");
  // Whole rows are one read; a narrower window one read per row.
  const bool whole_rows = window.col0 == 0 && window.col1 == n - 1;
  const std::size_t run = whole_rows ? window.samples() : std::size_t(window.width());
  std::vector<unsigned char> raw(2 * run);
  z.resize(window.samples());
  for (int row = window.row0; row <= window.row1; row += whole_rows ? window.height() : 1) {
    const std::uintmax_t at = 2 * (std::uintmax_t(row) * std::uintmax_t(n) + std::uintmax_t(window.col0));
    in.seekg(std::streamoff(at));
    in.read(reinterpret_cast<char*>(raw.data()), std::streamsize(raw.size()));
    if (!in || in.gcount() != std::streamsize(raw.size())) {
      throw DemError(path, "read only " + std::to_string(std::max<std::streamsize>(in.gcount(), 0)) + " of " +
                               std::to_string(raw.size()) + " bytes at offset " + std::to_string(at) +
                               " (file truncated or unreadable)");
    }
    double* out = z.data() + std::size_t(row - window.row0) * std::size_t(window.width());
    for (std::size_t i = 0; i < run; ++i) {
      const auto v = std::int16_t(std::uint16_t((raw[2 * i] << 8) | raw[2 * i + 1]));
      out[i] = v == -32768 ? std::numeric_limits<double>::quiet_NaN() : double(v);
    }
  }
}

}  // namespace detail

namespace {

Raster read_hgt(const std::string& path) {
  detail::HgtTile t = detail::hgt_tile(path);
  Raster r;
  r.width = r.height = t.n;
  detail::read_hgt_window(path, t.n, SampleRect{0, 0, t.n - 1, t.n - 1}, r.z);
  r.geo = std::move(t.geo);
  return r;
}

// ---------------------------------------------------------------------------------------------
// GDAL rasters

/// Metres per unit of a band's vertical unit string; nullopt when the unit is unknown.
std::optional<double> vertical_unit_to_metres(const std::string& unit) {
  const std::string u = lower(unit);
  if (u.empty() || u == "m" || u == "metre" || u == "metres" || u == "meter" || u == "meters") return 1.0;
  if (u == "ft" || u == "foot" || u == "feet" || u == "international foot") return 0.3048;
  if (u == "us-ft" || u == "ftus" || u == "us survey foot") return 1200.0 / 3937.0;
  return std::nullopt;
}

bool has_georeference(GDALDataset& ds) {
  QuietGdal quiet;
  double gt[6];
  const OGRSpatialReference* srs = ds.GetSpatialRef();
  return ds.GetGeoTransform(gt) == CE_None || (srs != nullptr && !srs->IsEmpty());
}

}  // namespace

namespace detail {

HeightScale height_scale(GDALRasterBand& band) {
  // Band scale and offset, then the vertical unit.
  HeightScale h;
  int has_scale = 0, has_offset = 0;
  const double scale = band.GetScale(&has_scale), offset = band.GetOffset(&has_offset);
  h.factor = has_scale ? scale : 1.0;
  h.shift = has_offset ? offset : 0.0;
  const char* unit = band.GetUnitType();
  h.unit = unit != nullptr ? unit : "";
  const std::optional<double> metres = vertical_unit_to_metres(h.unit);
  h.known = metres.has_value();
  if (h.known) h.factor *= *metres, h.shift *= *metres;
  return h;
}

GDALDatasetUniquePtr open_gdal(const std::string& path) {
  if (names_a_file(path)) require_file(path);
  register_gdal();
  QuietGdal quiet;
  GDALDatasetUniquePtr ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  if (!ds) throw DemError(path, "GDAL cannot read it as a raster: " + gdal_message("unknown format"));
  // Placed by ground control points alone: read through a warp north-up (bilinear, void outside
  // its footprint). Read as it is, it was taken for a heightmap image of 1 m cells, its relief
  // stretched by the true spacing.
  const GDALDataType type =
      ds->GetRasterCount() > 0 ? ds->GetRasterBand(1)->GetRasterDataType() : GDT_Float64;
  int gcps = 0;
  ds = north_up(std::move(ds),
                {"-r", "bilinear", "-dstnodata", "nan", "-ot", fits_float32(type) ? "Float32" : "Float64"},
                gcps);
  if (!ds)
    throw DemError(path, "it is placed by ground control points that GDAL cannot warp north-up: " +
                             gdal_message("GDALWarp failed"));
  if (gcps > 0) ds->SetMetadataItem("GCP_COUNT", std::to_string(gcps).c_str(), "terralod");  // see gdal_band
  return ds;
}

GdalBand gdal_band(const std::string& path, GDALDataset& ds, bool limit_size, int index) {
  QuietGdal quiet;
  // One band, or two when the second is an alpha band (gdalwarp -dstalpha writes them): its 0
  // samples are voids. It is read itself: GDAL makes it the first band's mask only when it is
  // Byte or UInt16, and gdalwarp gives it the heights' type (Int16 for SRTM). With `index`, that
  // band of any number (a BAG's elevation beside its uncertainty), and the last band as alpha
  // when it is one.
  const int bands = ds.GetRasterCount();
  if (bands == 0) {
    // A container of rasters (NetCDF variables, HDF5 datasets, GeoPackage tables): say their
    // names, which GDAL opens each raster by.
    std::vector<std::string> names;
    for (char** m = ds.GetMetadata("SUBDATASETS"); m != nullptr && *m != nullptr; ++m) {
      const std::string item = *m;
      const std::size_t eq = item.find('=');
      if (eq != std::string::npos && item.substr(0, eq).ends_with("_NAME"))
        names.push_back(item.substr(eq + 1));
    }
    if (!names.empty()) {
      std::string list;
      for (std::size_t i = 0; i < names.size() && i < 8; ++i) list += (i ? ", '" : "'") + names[i] + "'";
      if (names.size() > 8) list += " and " + std::to_string(names.size() - 8) + " more";
      throw DemError(path, "holds " + std::to_string(names.size()) +
                               " rasters and no band of its own: name the one to read instead of the file (" +
                               list + ")");
    }
  }
  const bool last_is_alpha = bands >= 2 && ds.GetRasterBand(bands)->GetColorInterpretation() == GCI_AlphaBand;
  if (index > 0 && index > bands) {
    throw DemError(path, "has " + std::to_string(bands) + " band" + (bands == 1 ? "" : "s") + "; band " +
                             std::to_string(index) + " was asked for");
  }
  if (index == 0 && bands != 1 && !(bands == 2 && last_is_alpha)) {
    throw DemError(path, "has " + std::to_string(bands) + " band" + (bands == 1 ? "" : "s") +
                             "; a DEM must have one (and may have an alpha band besides), or the band that "
                             "holds the heights must be named (--band N)");
  }
  if (index == 0) index = 1;
  const bool alpha = last_is_alpha && index != bands;
  GDALRasterBand* band = ds.GetRasterBand(index);
  const GDALDataType type = band->GetRasterDataType();
  if (GDALDataTypeIsComplex(type)) {
    throw DemError(path, std::string("band type ") + GDALGetDataTypeName(type) +
                             " is complex; a DEM needs real heights");
  }
  GdalBand b;
  b.width = ds.GetRasterXSize();
  b.height = ds.GetRasterYSize();
  if (limit_size) {
    check_dimensions(path, b.width, b.height);
  } else if (b.width < 2 || b.height < 2) {
    check_dimensions(path, b.width, b.height);  // its message for grids under 2 x 2
  }

  // Voids: the nodata value (compared in the band's own type), a real mask band, NaN/inf.
  int has_nodata = 0;
  b.nodata = band->GetNoDataValue(&has_nodata);
  b.has_nodata = has_nodata && !std::isnan(b.nodata);
  b.nodata_as_float = type == GDT_Float32;
  const int mask_flags = band->GetMaskFlags();
  b.index = index;
  b.alpha_index = alpha ? bands : 0;
  b.mask_band = !alpha && !(mask_flags & GMF_ALL_VALID) && !(mask_flags & GMF_NODATA);

  const HeightScale heights = height_scale(*band);
  b.factor = heights.factor, b.shift = heights.shift;
  if (const char* gcps = ds.GetMetadataItem("GCP_COUNT", "terralod"))  // see open_gdal
    b.height_note += std::string("; placed north-up by its ") + gcps + " ground control points";
  if (!heights.known)
    b.height_note += "; heights in unknown unit '" + heights.unit + "' taken as metres";
  else if (vertical_unit_to_metres(heights.unit) != 1.0)
    b.height_note += "; heights converted from '" + heights.unit + "' to metres";

  // Georeferencing.
  const OGRSpatialReference* srs = ds.GetSpatialRef();
  const char* wkt = ds.GetProjectionRef();
  b.geo.crs_wkt = wkt != nullptr ? wkt : "";
  double gt[6];
  if (ds.GetGeoTransform(gt) == CE_None) {
    georeference(b.geo, gt, srs);
  } else {
    b.geo.kind = Georef::Kind::None;
  }
  return b;
}

void read_gdal_window(const std::string& path, GDALDataset& ds, const GdalBand& b, SampleRect window,
                      std::vector<double>& z) {
  QuietGdal quiet;
  GDALRasterBand* band = ds.GetRasterBand(b.index);
  const int w = window.width(), h = window.height();
  z.resize(window.samples());
  if (band->RasterIO(GF_Read, window.col0, window.row0, w, h, z.data(), w, h, GDT_Float64, 0, 0) != CE_None) {
    throw DemError(path, "cannot read the samples: " + gdal_message("GDAL read error"));
  }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (b.has_nodata) {
    const float nodata_f = float(b.nodata);
    for (double& v : z) {
      if (b.nodata_as_float ? float(v) == nodata_f : v == b.nodata) v = nan;
    }
  }
  // Voids where a band reads 0: the alpha band, as doubles (bytes would round a float alpha
  // below 0.5 to 0), or the mask band, as bytes.
  const auto void_where_zero = [&](GDALRasterBand* m, auto zero, GDALDataType type, const char* what) {
    std::vector<decltype(zero)> v(z.size());
    if (m->RasterIO(GF_Read, window.col0, window.row0, w, h, v.data(), w, h, type, 0, 0) != CE_None)
      throw DemError(path,
                     std::string("cannot read the ") + what + " band: " + gdal_message("GDAL read error"));
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (v[i] == zero) z[i] = nan;
    }
  };
  if (b.alpha_index > 0) void_where_zero(ds.GetRasterBand(b.alpha_index), 0.0, GDT_Float64, "alpha");
  if (b.mask_band) void_where_zero(band->GetMaskBand(), std::uint8_t(0), GDT_Byte, "mask");
  for (double& v : z) {
    v = v * b.factor + b.shift;
    if (!is_height(v)) v = nan;
  }
}

}  // namespace detail

namespace {

Raster read_gdal(const std::string& path, GDALDataset& ds, int band) {
  detail::GdalBand b = detail::gdal_band(path, ds, true, band);
  Raster r;
  r.width = b.width;
  r.height = b.height;
  detail::read_gdal_window(path, ds, b, SampleRect{0, 0, b.width - 1, b.height - 1}, r.z);
  r.height_note = std::move(b.height_note);
  r.geo = std::move(b.geo);
  return r;
}

// ---------------------------------------------------------------------------------------------
// Common finishing: frame, voids.

}  // namespace

namespace detail {

pm::GridTransform world_transform(const std::string& path, int w, int h, const Georef& geo,
                                  const DemOptions& options, std::string& frame) {
  const auto& a = geo.a;
  pm::GridTransform t;
  switch (geo.kind) {
    case Georef::Kind::None: {
      const double s = options.heightmap_spacing;
      t = pm::GridTransform::north_up(0.0, double(h - 1) * s, s, s);
      frame = "image grid without georeferencing: north-up, spacing " + format_number(s) +
              " m, south-west sample at (0, 0)";
      break;
    }
    case Georef::Kind::Metric:
      t = pm::GridTransform{a[0], a[1], a[2], a[3], a[4], a[5]};
      frame = geo.description;
      break;
    case Georef::Kind::Geographic: {
      double lon0 = std::numeric_limits<double>::infinity(), lat0 = lon0;
      const std::array<std::pair<int, int>, 4> corners = {{{0, 0}, {w - 1, 0}, {0, h - 1}, {w - 1, h - 1}}};
      for (const auto& [c, rw] : corners) {
        const double lon = a[0] + c * a[1] + rw * a[2], lat = a[3] + c * a[4] + rw * a[5];
        if (!(std::abs(lat) <= 90.0 + 1e-9)) {
          throw DemError(path, "corner latitude " + format_number(lat) +
                                   " is outside [-90, 90]; the georeferencing is not geographic degrees");
        }
        lon0 = std::min(lon0, lon);
        lat0 = std::min(lat0, lat);
      }
      const double lat_c = a[3] + 0.5 * (w - 1) * a[4] + 0.5 * (h - 1) * a[5];
      const double kx = kEarthRadius * std::cos(lat_c * kDeg) * kDeg, ky = kEarthRadius * kDeg;
      t = pm::GridTransform{kx * (a[0] - lon0), kx * a[1], kx * a[2],
                            ky * (a[3] - lat0), ky * a[4], ky * a[5]};
      frame =
          "local equirectangular from " + geo.description +
          " lon/lat: x = R*cos(phi_c)*(lon-lon0)*pi/180, y = R*(lat-lat0)*pi/180, R = 6371008.8 m, lon0 = " +
          format_number(lon0) + ", lat0 = " + format_number(lat0) + ", phi_c = " + format_number(lat_c);
      break;
    }
  }
  const double det = t.determinant();
  if (!std::isfinite(t.x0) || !std::isfinite(t.y0) || !std::isfinite(det) || det == 0.0) {
    throw DemError(path, "the georeferencing is degenerate (zero or non-finite sample spacing)");
  }
  return t;
}

}  // namespace detail

namespace {

pm::Heightfield finish(const std::string& path, Raster&& r, const DemOptions& options) {
  check_dimensions(path, r.width, r.height);
  std::string frame;
  const pm::GridTransform transform = detail::world_transform(path, r.width, r.height, r.geo, options, frame);

  const std::size_t voids =
      std::size_t(std::count_if(r.z.begin(), r.z.end(), [](double v) { return !std::isfinite(v); }));
  if (voids == r.z.size()) {
    throw DemError(path, "has no valid sample (all " + std::to_string(voids) + " are void)");
  }

  pm::Heightfield hf(r.width, r.height);
  hf.transform = transform;
  hf.voids.voids = voids;
  if (voids > 0 && options.fill_voids) {
    VoidFillOptions fill;
    fill.on_solve = options.on_large_void;
    hf.voids.filled = fill_voids(r.z, r.width, r.height, fill).filled;
  }
  if (hf.voids.filled < voids) {  // not filling, or regions over VoidFillOptions::max_region_cells
    std::vector<std::uint8_t> mask(r.z.size(), 1);
    for (std::size_t i = 0; i < r.z.size(); ++i) {
      if (!std::isfinite(r.z[i])) {
        mask[i] = 0;
        r.z[i] = 0.0;
      }
    }
    hf.set_mask(std::move(mask));
  }
  hf.samples() = std::move(r.z);
  hf.crs_wkt = std::move(r.geo.crs_wkt);
  if (!hf.crs_wkt.empty() && r.geo.kind != Georef::Kind::None) {
    const auto& n = r.geo.native;
    hf.crs_transform = pm::GridTransform{n[0], n[1], n[2], n[3], n[4], n[5]};
  }
  hf.vertical_datum = std::move(r.geo.vertical_datum);
  hf.source = path;
  hf.frame = frame;
  hf = detail::apply_frame(path, std::move(hf), options.crs);
  hf.frame += r.height_note;
  return hf;
}

/// The format of `path` (Auto resolved), `ds` opened for Gdal.
Format format_of(const std::string& path, const DemOptions& options, GDALDatasetUniquePtr& ds) {
  const std::string ext = lower(fs::path(path).extension().string());
  if (options.format == Format::Auto) {
    if (ext == ".hgt") return Format::Hgt;
    if (ext == ".asc") return Format::AsciiGrid;
  } else if (options.format != Format::Gdal) {
    return options.format;
  }
  try {
    ds = detail::open_gdal(path);
  } catch (const DemError& e) {
    // An image GDAL has no driver for, such as an OpenEXR heightmap (what World Machine and
    // Gaea export): OpenImageIO reads it.
    if (options.format != Format::Auto || !fs::is_regular_file(path)) throw;
    if (!OIIO::ImageInput::open(path)) {
      const std::string msg = OIIO::geterror();
      throw DemError(path, e.problem() + "; OpenImageIO cannot read it as an image either: " +
                               (msg.empty() ? "unknown format" : msg));
    }
    return Format::Heightmap;
  }
  // An image without georeference (PNG, TIFF, PGM, ...) is a heightmap, read by OpenImageIO with
  // --vertical-scale; one with a georeference (for a PNG, a world file or GDAL's .aux.xml beside
  // it, as gdal_translate -of PNG writes) is a raster on it: read as a heightmap, a georeferenced
  // PNG's cells became 1 m and its relief was stretched by the true spacing.
  if (options.format == Format::Auto && !has_georeference(*ds) && detail::names_a_file(path)) {
    bool image = ext == ".tif" || ext == ".tiff" || ext == ".png";
    if (!image) {
      image = OIIO::ImageInput::open(path) != nullptr;
      if (!image) OIIO::geterror();  // not an image: a raster without georeference, read by GDAL
    }
    if (image) {
      ds.reset();
      return Format::Heightmap;
    }
  }
  return Format::Gdal;
}

}  // namespace

namespace detail {

Format dem_format(const std::string& path, const DemOptions& options, GDALDatasetUniquePtr& ds) {
  const Format f = format_of(path, options, ds);
  if (f != Format::Gdal && options.band > 1)
    throw DemError(path, "has one band (it is not read through GDAL); band " + std::to_string(options.band) +
                             " was asked for");
  // The scale was silently ignored for other files: their heights come in a unit of their own.
  if (f != Format::Heightmap && (options.vertical_scale != 1.0 || options.vertical_offset != 0.0))
    throw DemError(path,
                   "is no heightmap image: a vertical scale and offset apply to heightmaps only, whose raw "
                   "values have no unit; this file's heights are in its own unit (a GeoTIFF's band scale "
                   "and unit are applied: gdal_edit.py -scale S -offset O sets them)");
  return f;
}

void check_options(const DemOptions& o) {
  if (!std::isfinite(o.vertical_scale) || o.vertical_scale == 0.0) {
    throw std::invalid_argument("DemOptions::vertical_scale must be finite and non-zero");
  }
  if (!std::isfinite(o.vertical_offset))
    throw std::invalid_argument("DemOptions::vertical_offset must be finite");
  if (!std::isfinite(o.heightmap_spacing) || !(o.heightmap_spacing > 0.0)) {
    throw std::invalid_argument("DemOptions::heightmap_spacing must be finite and positive");
  }
  if (o.band < 0) throw std::invalid_argument("DemOptions::band must be >= 0");
  if (o.crs.empty())
    throw std::invalid_argument("DemOptions::crs must be 'native', 'auto' or a CRS, not empty");
}

}  // namespace detail

pm::Heightfield read_dem(const std::string& path, const DemOptions& options) {
  detail::check_options(options);
  try {
    GDALDatasetUniquePtr ds;
    switch (detail::dem_format(path, options, ds)) {
      case Format::Hgt:
        return finish(path, read_hgt(path), options);
      case Format::AsciiGrid:
        return finish(path, detail::read_ascii_grid(path), options);
      case Format::Heightmap:
        return finish(path, detail::read_heightmap(path, options), options);
      case Format::Auto:
      case Format::Gdal:
        return finish(path, read_gdal(path, *ds, options.band), options);
    }
    throw DemError(path, "unknown format");
  } catch (const fs::filesystem_error& e) {
    throw DemError(path, e.what());
  }
}

}  // namespace terralod::blocks
