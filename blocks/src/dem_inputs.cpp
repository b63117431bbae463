// Several DEM files, or a folder of them, as one raster (see DemInputs in dem_reader.hpp).
#include <gdal_alg.h>
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

/// A path that a VRT in /vsimem can name its source by (a relative one would be taken as
/// relative to the VRT's own folder).
std::string absolute_source(const std::string& path) {
  std::error_code ec;
  return (path.rfind("/vsi", 0) != 0 && fs::exists(path, ec)) ? fs::absolute(path, ec).string() : path;
}

/// Geographic tiles on both sides of the antimeridian (Fiji's S17E179 and S17W180) would mosaic
/// into a raster 360 degrees wide, nearly all void, that takes minutes to open and spans the
/// Earth. When every file is a north-up geographic raster and moving the western-hemisphere ones
/// 360 degrees east shortens the mosaic's longitude span below 180 degrees, each of those is
/// replaced by an in-memory VRT of it with its georeference moved (the samples are the file's),
/// named `prefix` + k; their names are added to `made`.
std::vector<std::string> across_antimeridian(const std::vector<std::string>& files, const std::string& prefix,
                                             std::vector<std::string>& made) {
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
    GDALDatasetUniquePtr src(GDALDataset::Open(absolute_source(files[k]).c_str(), GDAL_OF_RASTER));
    GDALDatasetH moved =
        opt && src ? GDALTranslate(name.c_str(), GDALDataset::ToHandle(src.get()), opt, nullptr) : nullptr;
    GDALTranslateOptionsFree(opt);
    if (moved == nullptr)
      throw DemError(files[k], "cannot move it 360 degrees east to join the tiles across the antimeridian (" +
                                   detail::gdal_message("GDALTranslate failed") + ")");
    GDALClose(moved);
    made.push_back(name);
    out.push_back(name);
  }
  return out;
}

/// What the mosaic needs to know of one input file.
struct FileFacts {
  OGRSpatialReference srs;  ///< empty when the file has none
  GDALDataType type = GDT_Unknown;
  double gt[6] = {0, 1, 0, 0, 0, 1};
  int width = 0, height = 0;
  bool alpha = false;  ///< a second band, alpha (gdalwarp -dstalpha writes heights so)
};

FileFacts file_facts(const std::string& path) {
  detail::QuietGdal quiet;
  GDALDatasetUniquePtr ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER));
  if (!ds || ds->GetRasterCount() < 1)
    throw DemError(path, "GDAL cannot read it as a raster (" + detail::gdal_message("no raster band") + ")");
  FileFacts f;
  if (const OGRSpatialReference* srs = ds->GetSpatialRef()) f.srs = *srs;
  f.type = ds->GetRasterBand(1)->GetRasterDataType();
  if (ds->GetGeoTransform(f.gt) != CE_None)
    throw DemError(path, "it has no georeference, so it has no place in a mosaic of several files");
  f.width = ds->GetRasterXSize(), f.height = ds->GetRasterYSize();
  f.alpha = ds->GetRasterCount() == 2 && ds->GetRasterBand(2)->GetColorInterpretation() == GCI_AlphaBand;
  return f;
}

bool same_crs(const OGRSpatialReference& a, const OGRSpatialReference& b) {
  const char* const options[] = {"IGNORE_DATA_AXIS_TO_SRS_AXIS_MAPPING=YES",
                                 "CRITERION=EQUIVALENT_EXCEPT_AXIS_ORDER_GEOGCRS", nullptr};
  return a.IsEmpty() == b.IsEmpty() && (a.IsEmpty() || a.IsSame(&b, options));
}

/// GDALBuildVRT joins only files of one CRS and one sample type. Inputs that mix them (tiles of
/// two UTM zones; SRTM's Int16 .hgt beside Copernicus' Float32 GeoTIFFs) are made alike: the
/// files outside the CRS that holds the most samples are each warped (bilinear, exact
/// transformations) to it in an in-memory VRT on the finest sample spacing of the files already
/// in it, its cells aligned to theirs so that the mosaic does not resample them again, and
/// outside its footprint a void; then, when sample types still differ, the others are read as
/// Float32 (or Float64 when a type does not fit a float), and band colour interpretations that
/// differ from the first file's are set to it. The VRTs read the files on demand:
/// nothing is copied. Names of the VRTs are `prefix` + k and are added to `made`; `note` says
/// what was done, for the mosaic's description.
std::vector<std::string> made_alike(const std::vector<std::string>& files, const std::string& prefix,
                                    std::vector<std::string>& made, std::string& note) {
  std::vector<FileFacts> facts;
  for (const std::string& f : files) facts.push_back(file_facts(f));
  // The CRS with the most samples (the first file's on a tie; a file without a CRS is then
  // the one that does not fit).
  std::size_t target = 0, most = 0;
  for (std::size_t i = 0; i < facts.size(); ++i) {
    if (facts[i].srs.IsEmpty()) continue;
    std::size_t n = 0;
    for (const FileFacts& g : facts)
      if (same_crs(facts[i].srs, g.srs)) n += std::size_t(g.width) * std::size_t(g.height);
    if (n > most) most = n, target = i;
  }
  const OGRSpatialReference& to = facts[target].srs;
  std::vector<std::string> out = files;
  std::vector<GDALDataType> types;
  double rx = 1e300, ry = 1e300;  // the finest spacing in the target CRS
  for (const FileFacts& f : facts)
    if (same_crs(f.srs, to)) rx = std::min(rx, std::abs(f.gt[1])), ry = std::min(ry, std::abs(f.gt[5]));
  const double ox = facts[target].gt[0], oy = facts[target].gt[3];  // a corner of a target cell
  std::size_t warped = 0;
  char* wkt = nullptr;
  to.exportToWkt(&wkt, nullptr);
  const std::string to_wkt = wkt ? wkt : "";
  CPLFree(wkt);
  const auto make = [&](std::size_t k, const char* what, auto&& run) {
    const std::string name = prefix + std::to_string(k) + ".vrt";
    detail::QuietGdal quiet;
    GDALDatasetUniquePtr src(GDALDataset::Open(absolute_source(out[k]).c_str(), GDAL_OF_RASTER));
    GDALDatasetH vrt = src ? run(name, GDALDataset::ToHandle(src.get())) : nullptr;
    if (vrt == nullptr)
      throw DemError(files[k], std::string("cannot ") + what + " it to join the other inputs (" +
                                   detail::gdal_message("GDAL failed") + ")");
    GDALClose(vrt);
    made.push_back(name);
    out[k] = name;
  };
  // Heights with an alpha band beside files without one (GDALBuildVRT wants one band count):
  // band 1 read with the alpha band as its mask, which the mosaic keeps (its other files valid
  // everywhere) and a warp below turns into NaN voids.
  const bool some_without_alpha =
      std::any_of(facts.begin(), facts.end(), [](const FileFacts& f) { return !f.alpha; });
  std::size_t unalpha = 0;
  for (std::size_t k = 0; k < facts.size(); ++k) {
    if (!facts[k].alpha || !some_without_alpha) continue;
    make(k, "read the heights of", [&](const std::string& name, GDALDatasetH src) -> GDALDatasetH {
      GDALTranslateOptions* opt =
          detail::gdal_options({"-of", "VRT", "-b", "1", "-mask", "2"}, GDALTranslateOptionsNew);
      GDALDatasetH vrt = opt ? GDALTranslate(name.c_str(), src, opt, nullptr) : nullptr;
      GDALTranslateOptionsFree(opt);
      return vrt;
    });
    ++unalpha;
  }
  for (std::size_t k = 0; k < facts.size(); ++k) {
    const FileFacts& f = facts[k];
    if (same_crs(f.srs, to)) {
      types.push_back(f.type);
      continue;
    }
    if (f.srs.IsEmpty() || to.IsEmpty())
      throw DemError(files[k], std::string(f.srs.IsEmpty() ? "it has no CRS while " : "it has a CRS while ") +
                                   files[target] + (f.srs.IsEmpty() ? " has one" : " has none") +
                                   ": a mosaic needs every file placed on the Earth (gdal_translate -a_srs "
                                   "gives one)");
    // Its footprint in the target CRS, widened to whole target cells.
    const GDALDataType type = detail::fits_float32(f.type) ? GDT_Float32 : GDT_Float64;
    make(k, "warp", [&](const std::string& name, GDALDatasetH src) -> GDALDatasetH {
      const std::string dst = "DST_SRS=" + to_wkt;
      const char* const transform_options[] = {dst.c_str(), nullptr};
      void* transform = GDALCreateGenImgProjTransformer2(src, nullptr, const_cast<char**>(transform_options));
      if (transform == nullptr) return nullptr;
      double gt[6], extent[4];
      int w = 0, h = 0;
      const CPLErr rc =
          GDALSuggestedWarpOutput2(src, GDALGenImgProjTransform, transform, gt, &w, &h, extent, 0);
      GDALDestroyGenImgProjTransformer(transform);
      if (rc != CE_None) return nullptr;
      const double x0 = ox + std::floor((extent[0] - ox) / rx) * rx,
                   x1 = ox + std::ceil((extent[2] - ox) / rx) * rx;
      const double y0 = oy + std::floor((extent[1] - oy) / ry) * ry,
                   y1 = oy + std::ceil((extent[3] - oy) / ry) * ry;
      const std::vector<std::string> args = {"-of",
                                             "VRT",
                                             "-t_srs",
                                             to_wkt,
                                             "-r",
                                             "bilinear",
                                             "-et",
                                             "0",
                                             "-dstnodata",
                                             "nan",
                                             "-ot",
                                             GDALGetDataTypeName(type),
                                             "-te",
                                             detail::gdal_number(x0),
                                             detail::gdal_number(y0),
                                             detail::gdal_number(x1),
                                             detail::gdal_number(y1),
                                             "-ts",
                                             std::to_string(std::llround((x1 - x0) / rx)),
                                             std::to_string(std::llround((y1 - y0) / ry))};
      GDALWarpAppOptions* opt = detail::gdal_options(args, GDALWarpAppOptionsNew);
      int usage_error = 0;
      GDALDatasetH vrt = opt ? GDALWarp(name.c_str(), nullptr, 1, &src, opt, &usage_error) : nullptr;
      GDALWarpAppOptionsFree(opt);
      return vrt;
    });
    types.push_back(type);
    ++warped;
  }
  // One sample type, and one colour interpretation, which means nothing for heights but which
  // GDALBuildVRT also wants alike: an SRTM .hgt tile's band is Undefined, a GeoTIFF's Gray.
  GDALDataType common = types[0];
  bool mixed = false;
  for (GDALDataType t : types) mixed |= t != types[0];
  if (mixed) {
    common = GDT_Float32;
    for (GDALDataType t : types)
      if (!detail::fits_float32(t)) common = GDT_Float64;
  }
  const auto interpretation = [&](std::size_t k) {
    detail::QuietGdal quiet;
    GDALDatasetUniquePtr ds(GDALDataset::Open(absolute_source(out[k]).c_str(), GDAL_OF_RASTER));
    return ds && ds->GetRasterCount() > 0 ? ds->GetRasterBand(1)->GetColorInterpretation() : GCI_Undefined;
  };
  std::string first_interpretation = GDALGetColorInterpretationName(interpretation(0));
  std::transform(first_interpretation.begin(), first_interpretation.end(), first_interpretation.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  std::size_t converted = 0;
  for (std::size_t k = 0; k < out.size(); ++k) {
    std::vector<std::string> args = {"-of", "VRT"};
    if (types[k] != common) args.insert(args.end(), {"-ot", GDALGetDataTypeName(common)});
    if (k > 0 && !EQUAL(GDALGetColorInterpretationName(interpretation(k)), first_interpretation.c_str()))
      args.insert(args.end(), {"-colorinterp", first_interpretation});
    if (args.size() == 2) continue;
    make(k, "convert", [&](const std::string& name, GDALDatasetH src) -> GDALDatasetH {
      GDALTranslateOptions* opt = detail::gdal_options(args, GDALTranslateOptionsNew);
      GDALDatasetH vrt = opt ? GDALTranslate(name.c_str(), src, opt, nullptr) : nullptr;
      GDALTranslateOptionsFree(opt);
      return vrt;
    });
    if (types[k] != common) ++converted;
  }
  if (warped)
    note += "; " + std::to_string(warped) + " warped to " + (to.GetName() ? to.GetName() : "the others' CRS");
  if (converted) note += "; " + std::to_string(converted) + " read as " + GDALGetDataTypeName(common);
  if (unalpha) note += "; " + std::to_string(unalpha) + " with its alpha band read as voids";
  return out;
}

/// Whether the sources of the VRT mosaic at `path` (GDALBuildVRT's, which it puts at the
/// mean sample spacing) are scaled: whether the inputs' spacings differ.
bool resamples(const std::string& path) {
  CPLXMLNode* root = CPLParseXMLFile(path.c_str());
  const CPLXMLNode* dataset = root ? CPLGetXMLNode(root, "=VRTDataset") : nullptr;
  bool scaled = false;
  for (CPLXMLNode* band = dataset ? dataset->psChild : nullptr; band; band = band->psNext) {
    if (band->eType != CXT_Element || std::string(band->pszValue) != "VRTRasterBand") continue;
    for (CPLXMLNode* s = band->psChild; s; s = s->psNext) {
      if (s->eType != CXT_Element) continue;
      const char* sw = CPLGetXMLValue(s, "SrcRect.xSize", nullptr);
      const char* dw = CPLGetXMLValue(s, "DstRect.xSize", nullptr);
      const char* sh = CPLGetXMLValue(s, "SrcRect.ySize", nullptr);
      const char* dh = CPLGetXMLValue(s, "DstRect.ySize", nullptr);
      if (sw && dw && sh && dh &&
          (std::abs(CPLAtof(sw) - CPLAtof(dw)) > 1e-6 * CPLAtof(dw) ||
           std::abs(CPLAtof(sh) - CPLAtof(dh)) > 1e-6 * CPLAtof(dh)))
        scaled = true;
    }
  }
  if (root) CPLDestroyXMLNode(root);
  return scaled;
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
    if (detail::names_a_file(f) && !fs::exists(f)) throw DemError(f, "no such file");
  static std::atomic<int> serial{0};
  path_ = "/vsimem/terralod_inputs_" + std::to_string(::getpid()) + "_" + std::to_string(serial++) + ".vrt";
  detail::register_gdal();
  std::vector<std::string> args;  // GDALBuildVRT's
  const auto mosaic = [&](const std::vector<std::string>& sources) {
    if (const std::string why = detail::build_vrt(path_, sources, args); !why.empty())
      throw DemError(folder.empty() ? files[0] : folder, "cannot mosaic the " + std::to_string(files.size()) +
                                                             " inputs into one raster (" + why + ")");
  };
  std::string note;
  try {
    // The files are looked at one by one (each opened once more) only when GDALBuildVRT refuses
    // them or the mosaic spans more than half the Earth: a folder of thousands of tiles opens in
    // the time GDALBuildVRT takes, and only unusual inputs pay for finding out more.
    std::vector<std::string> sources = files;
    if (!detail::build_vrt(path_, sources).empty()) {
      sources = made_alike(files, path_ + ".alike", made_, note);
      mosaic(sources);
    }
    // GDALBuildVRT puts files of different sample spacings on their mean spacing, which drops
    // detail from the finer ones: the finest is kept, the coarser files resampled bilinearly
    // (GDAL's default, nearest, would make them steps).
    if (resamples(path_)) {
      args = {"-resolution", "highest", "-r", "bilinear"};
      mosaic(sources);
      note += "; on the finest sample spacing, coarser files resampled bilinearly";
    }
    if (spans_half_the_earth(path_)) {
      const std::size_t before = made_.size();
      const std::vector<std::string> moved = across_antimeridian(sources, path_ + ".east", made_);
      if (made_.size() > before) mosaic(moved);
    }
  } catch (...) {  // no destructor runs: the VRTs made for the mosaic go here
    for (const std::string& s : made_) VSIUnlink(s.c_str());
    throw;
  }
  owned_ = true;
  description_ = "mosaic of " + std::to_string(files.size()) + (files.size() == 1 ? " file: " : " files: ");
  for (std::size_t i = 0; i < files.size() && i < 4; ++i)
    description_ += (i ? ", " : "") + fs::path(files[i]).filename().string();
  if (files.size() > 4) description_ += ", ...";
  if (!folder.empty()) description_ += " (in " + folder + ")";
  description_ += note;
}

DemInputs::~DemInputs() {
  if (owned_) VSIUnlink(path_.c_str());
  for (const std::string& s : made_) VSIUnlink(s.c_str());
}

}  // namespace terralod::blocks
