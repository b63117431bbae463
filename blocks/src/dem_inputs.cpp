// Several DEM files, or a folder of them, as one raster (see DemInputs in dem_reader.hpp).
#include <gdal_priv.h>
#include <gdal_utils.h>
#include <ogr_spatialref.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include "gdal_support.hpp"
#include "terralod/blocks/dem_reader.hpp"

namespace terralod::blocks {
namespace {

namespace fs = std::filesystem;

bool is_raster_name(const fs::path& p) {
  // Not .vrt: a folder of tiles often holds a VRT over them too, which would count them twice
  // (a VRT is given as an --input of its own).
  static const std::set<std::string> kExtensions = {".tif", ".tiff", ".hgt", ".asc",
                                                    ".img", ".dem",  ".bil", ".flt"};
  std::string name = p.filename().string();
  std::transform(name.begin(), name.end(), name.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  // SRTM tiles as they are downloaded (N44W072.SRTMGL1.hgt.zip): GDAL reads them zipped.
  if (name.size() > 8 && name.compare(name.size() - 8, 8, ".hgt.zip") == 0) return true;
  return kExtensions.count(fs::path(name).extension().string()) != 0;
}

/// Geographic tiles on both sides of the antimeridian (Fiji's S17E179 and S17W180) would mosaic
/// into a raster 360 degrees wide, nearly all void, that takes minutes to open and spans the
/// Earth. When every file is a north-up geographic raster and moving the western-hemisphere ones
/// 360 degrees east shortens the mosaic's longitude span below 180 degrees, each of those is
/// replaced by an in-memory VRT of it with its georeference moved (the samples are the file's),
/// named `prefix` + k; their names are added to `shifted`.
std::vector<std::string> across_antimeridian(const std::vector<std::string>& files, const std::string& prefix,
                                             std::vector<std::string>& shifted) {
  struct Extent {
    double west, east, north, south;
  };
  std::vector<Extent> ext;
  for (const std::string& f : files) {
    GDALDatasetUniquePtr ds(GDALDataset::Open(f.c_str(), GDAL_OF_RASTER));
    double gt[6];
    const OGRSpatialReference* srs = ds ? ds->GetSpatialRef() : nullptr;
    if (!ds || srs == nullptr || !srs->IsGeographic() || ds->GetGeoTransform(gt) != CE_None || gt[2] != 0.0 ||
        gt[4] != 0.0 || gt[1] <= 0.0)
      return files;
    ext.push_back({gt[0], gt[0] + gt[1] * ds->GetRasterXSize(), gt[3], gt[3] + gt[5] * ds->GetRasterYSize()});
  }
  double w0 = 1e300, e0 = -1e300, w1 = 1e300, e1 = -1e300;  // spans as they are, and moved
  for (const Extent& x : ext) {
    const double s = 0.5 * (x.west + x.east) < 0.0 ? 360.0 : 0.0;
    w0 = std::min(w0, x.west), e0 = std::max(e0, x.east);
    w1 = std::min(w1, x.west + s), e1 = std::max(e1, x.east + s);
  }
  if (e0 - w0 <= 180.0 || e1 - w1 >= e0 - w0 || e1 - w1 > 180.0) return files;
  std::vector<std::string> out;
  for (std::size_t k = 0; k < files.size(); ++k) {
    const Extent& x = ext[k];
    if (0.5 * (x.west + x.east) >= 0.0) {
      out.push_back(files[k]);
      continue;
    }
    const std::string name = prefix + std::to_string(k) + ".vrt";
    const std::vector<std::string> args = {"-of",
                                           "VRT",
                                           "-a_ullr",
                                           detail::gdal_number(x.west + 360.0),
                                           detail::gdal_number(x.north),
                                           detail::gdal_number(x.east + 360.0),
                                           detail::gdal_number(x.south)};
    GDALTranslateOptions* opt = detail::gdal_options(args, GDALTranslateOptionsNew);
    GDALDatasetUniquePtr src(GDALDataset::Open(files[k].c_str(), GDAL_OF_RASTER));
    GDALDatasetH moved =
        opt && src ? GDALTranslate(name.c_str(), GDALDataset::ToHandle(src.get()), opt, nullptr) : nullptr;
    GDALTranslateOptionsFree(opt);
    if (moved == nullptr)
      throw DemError(files[k], "cannot move it 360 degrees east to join the tiles across the antimeridian (" +
                                   detail::gdal_message("GDALTranslate failed") + ")");
    GDALClose(moved);
    shifted.push_back(name);
    out.push_back(name);
  }
  return out;
}

/// Whether the raster at `path` is geographic and wider than 180 degrees of longitude.
bool spans_half_the_earth(const std::string& path) {
  GDALDatasetUniquePtr ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER));
  double gt[6];
  const OGRSpatialReference* srs = ds ? ds->GetSpatialRef() : nullptr;
  return srs != nullptr && srs->IsGeographic() && ds->GetGeoTransform(gt) == CE_None &&
         std::abs(gt[1] * ds->GetRasterXSize()) + std::abs(gt[2] * ds->GetRasterYSize()) > 180.0;
}

}  // namespace

DemInputs::DemInputs(const std::vector<std::string>& inputs) {
  if (inputs.empty()) throw DemError("--input", "no input given");
  std::vector<std::string> files;
  std::string folder;
  for (const std::string& in : inputs) {
    std::error_code ec;
    if (fs::is_directory(in, ec)) {
      std::vector<std::string> found;
      for (const auto& e : fs::directory_iterator(in, ec))
        if (e.is_regular_file() && is_raster_name(e.path())) found.push_back(e.path().string());
      if (ec) throw DemError(in, "cannot list the folder: " + ec.message());
      if (found.empty())
        throw DemError(
            in, "the folder holds no elevation file (.tif .tiff .hgt .hgt.zip .asc .img .dem .bil .flt)");
      std::sort(found.begin(), found.end());
      files.insert(files.end(), found.begin(), found.end());
      folder = in;
    } else {
      files.push_back(in);
    }
  }
  files_ = files.size();
  if (files.size() == 1 && folder.empty()) {
    path_ = description_ = files[0];
    return;
  }
  for (const std::string& f : files)
    if (!fs::exists(f)) throw DemError(f, "no such file");
  static std::atomic<int> serial{0};
  path_ = "/vsimem/terralod_inputs_" + std::to_string(::getpid()) + "_" + std::to_string(serial++) + ".vrt";
  detail::register_gdal();
  const auto mosaic = [&](const std::vector<std::string>& sources) {
    if (const std::string why = detail::build_vrt(path_, sources); !why.empty())
      throw DemError(folder.empty() ? files[0] : folder, "cannot mosaic the " + std::to_string(files.size()) +
                                                             " inputs into one raster (" + why + ")");
  };
  try {
    // The files are looked at one by one (each opened once more) only when the mosaic spans
    // more than half the Earth: a folder of thousands of tiles opens in the time GDALBuildVRT
    // takes, and only tiles across the antimeridian pay for finding it out.
    mosaic(files);
    if (spans_half_the_earth(path_)) {
      const std::vector<std::string> moved = across_antimeridian(files, path_ + ".east", shifted_);
      if (!shifted_.empty()) mosaic(moved);
    }
  } catch (...) {  // no destructor runs: the moved tiles' VRTs go here
    for (const std::string& s : shifted_) VSIUnlink(s.c_str());
    throw;
  }
  owned_ = true;
  description_ = "mosaic of " + std::to_string(files.size()) + (files.size() == 1 ? " file: " : " files: ");
  for (std::size_t i = 0; i < files.size() && i < 4; ++i)
    description_ += (i ? ", " : "") + fs::path(files[i]).filename().string();
  if (files.size() > 4) description_ += ", ...";
  if (!folder.empty()) description_ += " (in " + folder + ")";
}

DemInputs::~DemInputs() {
  if (owned_) VSIUnlink(path_.c_str());
  for (const std::string& s : shifted_) VSIUnlink(s.c_str());
}

}  // namespace terralod::blocks
