// Private to terralod::blocks: GDAL registered once per process, whoever asks first; its error
// messages taken instead of printed; VRT mosaics; height datums' vertical CRSs.
#pragma once

#include <gdal_priv.h>
#include <gdal_utils.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <string>
#include <vector>

namespace terralod::blocks::detail {

/// GDAL's block cache capped to 64 MiB while one of these lives (windowed DEM sources, an
/// image's warp), unless the process set GDAL_CACHEMAX (environment or config option): GDAL's
/// default, 5 % of RAM, would grow with the raster read. Restored when the last one ends.
class CacheCap {
 public:
  CacheCap() {
    std::lock_guard lock(mutex());
    State& s = state();
    if (s.open++ == 0 && CPLGetConfigOption("GDAL_CACHEMAX", nullptr) == nullptr) {
      s.saved = GDALGetCacheMax64();
      s.capped = true;
      GDALSetCacheMax64(std::min<GIntBig>(s.saved, GIntBig(64) << 20));
    }
  }
  ~CacheCap() {
    std::lock_guard lock(mutex());
    State& s = state();
    if (--s.open == 0 && s.capped) {
      GDALSetCacheMax64(s.saved);
      s.capped = false;
    }
  }
  CacheCap(const CacheCap&) = delete;
  CacheCap& operator=(const CacheCap&) = delete;

 private:
  struct State {
    int open = 0;
    bool capped = false;
    GIntBig saved = 0;
  };
  static std::mutex& mutex() {
    static std::mutex m;
    return m;
  }
  static State& state() {
    static State s;
    return s;
  }
};

/// `s` in lower case (ASCII): names, units and keys compared without case.
inline std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return s;
}

/// The vertical CRS of a height datum's name, as PROJ and GDAL take it: "EPSG:5773" for EGM96
/// (and for no name: the datum SRTM and most DEMs use), "EPSG:3855" for EGM2008, "" for
/// ellipsoidal heights ("ellipsoid", "WGS 84", vertical_datum_of's "WGS 84 ellipsoidal height"),
/// else the name itself.
inline std::string vertical_crs(const std::string& datum) {
  const std::string d = lower(datum);
  if (d == "wgs84" || d == "wgs 84" || d.find("ellipsoid") != std::string::npos) return "";
  if (d.find("egm2008") != std::string::npos || d.find("egm08") != std::string::npos) return "EPSG:3855";
  if (d.empty() || d.find("egm96") != std::string::npos) return "EPSG:5773";
  return datum;
}

/// Whether `srs` is a 3D geographic or projected CRS (EPSG:4979): its third axis is the height
/// above its ellipsoid, which is then the heights' datum.
inline bool has_ellipsoidal_height_axis(const OGRSpatialReference& srs) {
  return !srs.IsCompound() && (srs.IsGeographic() || srs.IsProjected()) && srs.GetAxesCount() == 3;
}

/// The name of `srs`'s vertical CRS ("EGM96 height"), the vertical part of a compound CRS;
/// "<ellipsoid> ellipsoidal height" for a 3D geographic or projected CRS (EPSG:4979), whose
/// third axis is the height above its ellipsoid; "" when it has none.
inline std::string vertical_datum_of(const OGRSpatialReference& srs) {
  if (srs.IsEmpty()) return "";
  if (has_ellipsoidal_height_axis(srs)) {
    const char* ellipsoid = srs.GetAttrValue("SPHEROID");
    return std::string(ellipsoid != nullptr ? ellipsoid : "unnamed") + " ellipsoidal height";
  }
  if (!srs.IsCompound()) return "";
  const char* vertical = srs.GetAttrValue("COMPD_CS|VERT_CS");
  if (vertical == nullptr) vertical = srs.GetAttrValue("COMPOUNDCRS|VERTCRS");
  return vertical != nullptr ? vertical : "";
}

/// Whether `path` names a file of the file system, rather than a GDAL virtual file (/vsizip/...,
/// /vsicurl/...) or a GDAL dataset name, such as a subdataset of a NetCDF, HDF5 or GeoPackage
/// file (NETCDF:"dem.nc":z, GPKG:dem.gpkg:table), which only GDAL can check.
inline bool names_a_file(const std::string& path) {
  if (path.starts_with("/vsi")) return false;
  std::error_code ec;
  if (std::filesystem::exists(path, ec)) return true;
  const std::size_t colon = path.find(':');
  return colon == std::string::npos || colon < 2 ||
         !std::all_of(path.begin(), path.begin() + std::ptrdiff_t(colon),
                      [](unsigned char c) { return std::isalnum(c) || c == '_'; });
}

/// Registers GDAL's drivers, and unless the user's environment says otherwise, keeps GDAL from
/// listing a file's folder each time it opens one (GDAL_DISABLE_READDIR_ON_OPEN): sidecar files
/// (.prj, .hdr, .aux.xml) are then looked for by name. A mosaic opens every tile once to build its
/// VRT and again, through the VRT's pool of open files, as block windows are read; with the
/// listing, each open reads the whole folder, which grows with the square of the tiles in it
/// (900 tiles: the build's opening took 1.2 s, 0.87 s without; a quarter of it in ext4_readdir).
inline void register_gdal() {
  static std::once_flag once;
  std::call_once(once, [] {
    if (CPLGetConfigOption("GDAL_DISABLE_READDIR_ON_OPEN", nullptr) == nullptr)
      CPLSetConfigOption("GDAL_DISABLE_READDIR_ON_OPEN", "TRUE");
    GDALAllRegister();
  });
}

/// A number with every digit (%.17g), as GDAL's utilities take coordinates: six decimals can
/// misalign a tile and make GDAL resample it.
inline std::string gdal_number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

/// The options of a GDAL utility (GDALTranslateOptionsNew, GDALWarpAppOptionsNew, ...) from its
/// command-line arguments; nullptr when GDAL rejects them (gdal_message says why).
template <typename Make>
auto gdal_options(const std::vector<std::string>& args, Make make) {
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  return make(argv.data(), nullptr);
}

/// Silences GDAL's error printing for the current thread while alive: its messages are taken
/// into our errors (gdal_message) instead of being printed.
class QuietGdal {
 public:
  QuietGdal() {
    CPLPushErrorHandler(CPLQuietErrorHandler);
    CPLErrorReset();
  }
  ~QuietGdal() { CPLPopErrorHandler(); }
  QuietGdal(const QuietGdal&) = delete;
  QuietGdal& operator=(const QuietGdal&) = delete;
};

/// GDAL's last error message, or `fallback` when it has none.
inline std::string gdal_message(const std::string& fallback) {
  const char* msg = CPLGetLastErrorMsg();
  return (msg != nullptr && *msg != '\0') ? std::string(msg) : fallback;
}

/// Writes `dest` (a file or a /vsimem path) as a VRT mosaic of `files` (GDALBuildVRT with the
/// command-line arguments `args`; later files win where they overlap). Returns "" on success,
/// else GDAL's reason, with nothing left at `dest`; a file GDALBuildVRT would skip with a
/// warning (another CRS or band count) is a failure, not a hole in the mosaic.
inline std::string build_vrt(const std::string& dest, const std::vector<std::string>& files,
                             const std::vector<std::string>& args = {}) {
  register_gdal();
  QuietGdal quiet;  // its messages go into ours, not to stderr as well
  std::vector<const char*> list;
  for (const std::string& f : files) list.push_back(f.c_str());
  GDALBuildVRTOptions* options = args.empty() ? nullptr : gdal_options(args, GDALBuildVRTOptionsNew);
  if (!args.empty() && options == nullptr) return gdal_message("GDAL rejected the mosaic's options");
  int usage_error = 0;
  GDALDatasetH vrt =
      GDALBuildVRT(dest.c_str(), int(list.size()), nullptr, list.data(), options, &usage_error);
  GDALBuildVRTOptionsFree(options);
  std::string gdal = CPLGetLastErrorMsg();
  if (vrt) GDALClose(vrt);
  const bool skipped = gdal.find("Skipping") != std::string::npos;
  if (vrt && CPLGetLastErrorType() < CE_Failure && !skipped) return "";
  VSIUnlink(dest.c_str());
  return gdal.empty() ? std::string("GDALBuildVRT failed") : gdal;
}

/// Whether every value of the sample type `t` is exact in a float.
inline bool fits_float32(GDALDataType t) {
  return t == GDT_Byte || t == GDT_Int16 || t == GDT_UInt16 || t == GDT_Float32;
}

/// `ds` itself, or, when it is placed by ground control points alone (no geotransform, three
/// GCPs or more: scanned maps, raw products), a VRT that warps it north-up in the GCPs' CRS
/// (gdalwarp's own grid, exact transformations, and `args`: resampling, nodata, type) and holds
/// the file's dataset, closing it when it is closed. `gcps` gets their number (0: `ds` as it was).
/// nullptr when GDAL cannot warp it (gdal_message says why).
inline GDALDatasetUniquePtr north_up(GDALDatasetUniquePtr ds, const std::vector<std::string>& args,
                                     int& gcps) {
  gcps = 0;
  double gt[6];
  if (!ds || ds->GetGCPCount() < 3 || ds->GetGeoTransform(gt) == CE_None || ds->GetRasterCount() < 1)
    return ds;
  gcps = ds->GetGCPCount();
  std::vector<std::string> all = {"-of", "VRT", "-et", "0"};
  all.insert(all.end(), args.begin(), args.end());
  GDALWarpAppOptions* options = gdal_options(all, GDALWarpAppOptionsNew);
  GDALDatasetH src = GDALDataset::ToHandle(ds.get());
  int usage_error = 0;
  GDALDatasetH warped = options ? GDALWarp("", nullptr, 1, &src, options, &usage_error) : nullptr;
  GDALWarpAppOptionsFree(options);
  if (warped == nullptr) return nullptr;
  GDALDereferenceDataset(src);  // the VRT's reference is the one left
  (void)ds.release();
  return GDALDatasetUniquePtr(GDALDataset::FromHandle(warped));
}

}  // namespace terralod::blocks::detail
