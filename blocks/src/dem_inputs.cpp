// Several DEM files, or a folder of them, as one raster (see DemInputs in dem_reader.hpp).
#include <gdal_alg.h>
#include <gdal_priv.h>
#include <gdal_utils.h>
#include <ogr_spatialref.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "dem_raster.hpp"
#include "gdal_support.hpp"
#include "terralod/blocks/dem_reader.hpp"

namespace terralod::blocks {
namespace {

namespace fs = std::filesystem;

using detail::lower;

bool is_raster_name(const fs::path& p) {
  // Not .vrt: a folder of tiles often holds a VRT over them too, which would count them twice
  // (a VRT is given as an --input of its own). .dt0 .dt1 .dt2: DTED, level 0, 1 and 2.
  static const std::set<std::string> kExtensions = {".tif", ".tiff", ".hgt", ".asc", ".img", ".dem",
                                                    ".bil", ".flt",  ".dt0", ".dt1", ".dt2"};
  const std::string name = lower(p.filename().string());
  // SRTM tiles as they are downloaded (N44W072.SRTMGL1.hgt.zip): GDAL reads them zipped.
  if (name.size() > 8 && name.ends_with(".hgt.zip")) return true;
  return kExtensions.count(fs::path(name).extension().string()) != 0;
}

/// The problem of a folder (`archives`: whose archives are read too) or archive without elevation
/// files: `what` ("the archive holds"), the names looked for, and the `skipped` quality layers.
std::string no_elevation_file(const std::string& what, bool archives, std::size_t skipped) {
  return what + " no elevation file (.tif .tiff .hgt .hgt.zip .asc .img .dem .bil .flt .dt0 .dt1 .dt2" +
         (archives ? ", or archives of them: .zip .tar .tar.gz .tgz" : "") +
         (skipped ? ", other than " + std::to_string(skipped) + " quality layer" + (skipped == 1 ? "" : "s")
                  : std::string()) +
         ")";
}

/// Layers that elevation products ship beside each tile's heights, on the same cells, which a
/// folder of tiles must not mosaic as heights: ASTER GDEM's count of scenes per sample
/// (ASTGTMV003_N44W072_num.tif beside ..._dem.tif) and Copernicus DEM's masks (..._EDM, _FLM,
/// _HEM, _WBM.tif, in each tile's AUXFILES folder).
bool is_quality_layer(const fs::path& p) {
  const std::string stem = lower(p.stem().string());
  for (const char* suffix : {"_num", "_edm", "_flm", "_hem", "_wbm"})
    if (stem.size() > 4 && stem.ends_with(suffix)) return true;
  return false;
}

/// GDAL's file system prefix for the archive `p` (zip, or tar, gzipped or not, by its name), or
/// "" for other files. An SRTM .hgt.zip is a raster (is_raster_name), not an archive here.
std::string archive_prefix(const fs::path& p) {
  const std::string name = lower(p.filename().string());
  const auto ends = [&](const char* s) { return name.size() > std::strlen(s) && name.ends_with(s); };
  if (ends(".hgt.zip")) return "";
  if (ends(".zip")) return "/vsizip/";
  if (ends(".tar") || ends(".tar.gz") || ends(".tgz")) return "/vsitar/";
  return "";
}

/// The elevation files inside the archive at `path`, as GDAL paths into it (GDAL reads them in
/// place, nothing is extracted), at any depth, sorted; quality layers and files in AUXFILES folders
/// are counted in `skipped` and left out. Tiles come as such archives: ASTER GDEM's zip holds a
/// tile's _dem.tif and _num.tif, Copernicus DEM's tar its DEM and AUXFILES folders.
std::vector<std::string> archive_tiles(const std::string& path, std::size_t& skipped) {
  std::error_code ec;
  const std::string root = archive_prefix(path) + fs::absolute(path, ec).string();
  detail::register_gdal();
  char** list = VSIReadDirRecursive(root.c_str());
  if (list == nullptr)
    throw DemError(path, "cannot list the archive (" + detail::gdal_message("GDAL cannot read it") + ")");
  std::vector<std::string> found;
  for (char** e = list; *e != nullptr; ++e) {
    const fs::path entry(*e);
    if (!is_raster_name(entry)) continue;
    bool auxiliary = is_quality_layer(entry);
    for (const fs::path& part : entry.parent_path())
      auxiliary = auxiliary || lower(part.string()) == "auxfiles";
    if (auxiliary)
      ++skipped;
    else
      found.push_back(root + "/" + *e);
  }
  CSLDestroy(list);
  std::sort(found.begin(), found.end());
  return found;
}

/// The elevation files of a folder, sorted: its own (those in the archives among them included),
/// or when it holds none, those of its subfolders at any depth (Copernicus DEM keeps each tile in
/// a folder of its own, DTED in a folder per longitude), without Copernicus's AUXFILES folders and
/// quality layers (is_quality_layer), which are counted in `skipped`. Symbolic links to folders are
/// not followed. When its own files are its tiles, its subfolders (hidden ones aside) are counted in
/// `unsearched`, for the description.
std::vector<std::string> folder_tiles(const std::string& folder, std::size_t& skipped,
                                      std::size_t& unsearched) {
  std::vector<std::string> found;
  std::error_code ec;
  const auto take = [&](const fs::directory_entry& e) {
    if (!e.is_regular_file(ec)) return;
    if (!archive_prefix(e.path()).empty()) {
      const std::vector<std::string> inside = archive_tiles(e.path().string(), skipped);
      found.insert(found.end(), inside.begin(), inside.end());
    } else if (is_raster_name(e.path())) {
      if (is_quality_layer(e.path()))
        ++skipped;
      else
        found.push_back(e.path().string());
    }
  };
  unsearched = 0;
  for (const auto& e : fs::directory_iterator(folder, ec)) {
    take(e);
    std::error_code dir_ec;  // only counted
    unsearched += e.is_directory(dir_ec) && !e.path().filename().string().starts_with(".");
  }
  if (ec) throw DemError(folder, "cannot list the folder: " + ec.message());
  if (found.empty()) {  // its subfolders, at any depth
    skipped = unsearched = 0;
    fs::recursive_directory_iterator it(folder, fs::directory_options::skip_permission_denied, ec), end;
    for (; !ec && it != end; it.increment(ec)) {
      if (it->is_directory(ec) && lower(it->path().filename().string()) == "auxfiles") {
        it.disable_recursion_pending();
        std::error_code aux_ec;  // only counted: an unreadable one is left out all the same
        for (const auto& e : fs::directory_iterator(it->path(), aux_ec))
          skipped += e.is_regular_file(aux_ec) && is_raster_name(e.path());
        continue;
      }
      take(*it);
    }
    if (ec) throw DemError(folder, "cannot list the folder: " + ec.message());
  }
  std::sort(found.begin(), found.end());
  return found;
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
  bool alpha = false;           ///< a second band, alpha (gdalwarp -dstalpha writes heights so)
  detail::HeightScale heights;  ///< how its samples become metres
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
  f.heights = detail::height_scale(*ds->GetRasterBand(1));
  return f;
}

/// Whether every file's samples become metres alike (band scale, offset and vertical unit:
/// detail::height_scale); `first` is the first file's. GDALBuildVRT keeps none of them, so a
/// mosaic of tiles in feet read as metres, 3.28 times too high, and one of tiles in metres and
/// in feet mixed the two. Opens every file once more (900 GeoTIFF tiles: within the noise of the
/// mosaic's opening).
bool heights_alike(const std::vector<std::string>& files, detail::HeightScale& first) {
  bool alike = true;
  for (std::size_t k = 0; k < files.size(); ++k) {
    detail::QuietGdal quiet;
    GDALDatasetUniquePtr ds(GDALDataset::Open(files[k].c_str(), GDAL_OF_RASTER));
    if (!ds || ds->GetRasterCount() < 1) continue;  // GDALBuildVRT or file_facts say why
    const detail::HeightScale h = detail::height_scale(*ds->GetRasterBand(1));
    if (k == 0) first = h;
    alike = alike && h == first;
  }
  return alike;
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
/// differ from the first file's are set to it. With `floats`, files of integer samples are read
/// as Float32 (Float64) even when all are alike, so that the mosaic's nodata value can be NaN.
/// The VRTs read the files on demand: nothing is copied. Names of the VRTs are `prefix` + n and
/// are added to `made`; `note` says what was done, for the mosaic's description.
std::vector<std::string> made_alike(const std::vector<std::string>& files, const std::string& prefix,
                                    std::vector<std::string>& made, std::string& note, bool floats = false) {
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
  // Files warped from another vertical datum, by (datum, whether their heights were converted):
  // GDALWarp shifts heights between datums where PROJ has the transformation (EGM96 to
  // ellipsoidal heights, through proj-data's egm96_15.gtx), and leaves them as they are where it
  // lacks a geoid grid (EGM2008 and EGM96 without egm08_25.gtx), or where either CRS names no
  // vertical datum. The description says which.
  const std::string to_datum = detail::vertical_datum_of(to);
  std::map<std::pair<std::string, bool>, std::size_t> datums;
  char* wkt = nullptr;
  to.exportToWkt(&wkt, nullptr);
  const std::string to_wkt = wkt ? wkt : "";
  CPLFree(wkt);
  const auto make = [&](std::size_t k, const char* what, auto&& run) {
    // Named by how many were made: a file may be made alike in two steps (alpha, then type).
    const std::string name = prefix + std::to_string(made.size()) + ".vrt";
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
  // Heights in other units, or scaled: each read in metres, as Float64 (exact for every type).
  const bool heights_differ = std::any_of(
      facts.begin(), facts.end(), [&](const FileFacts& f) { return !(f.heights == facts[0].heights); });
  std::size_t in_metres = 0;
  for (std::size_t k = 0; k < facts.size() && heights_differ; ++k) {
    const detail::HeightScale& h = facts[k].heights;
    if (h.metres()) continue;
    make(k, "convert the heights of", [&](const std::string& name, GDALDatasetH src) -> GDALDatasetH {
      // metres = sample * factor + shift: the linear map of [0, 1] onto [shift, shift + factor].
      const std::vector<std::string> args = {"-of",
                                             "VRT",
                                             "-ot",
                                             "Float64",
                                             "-scale",
                                             "0",
                                             "1",
                                             detail::gdal_number(h.shift),
                                             detail::gdal_number(h.shift + h.factor)};
      GDALTranslateOptions* opt = detail::gdal_options(args, GDALTranslateOptionsNew);
      GDALDatasetH vrt = opt ? GDALTranslate(name.c_str(), src, opt, nullptr) : nullptr;
      GDALTranslateOptionsFree(opt);
      if (vrt != nullptr) {  // a metres band: no scale, offset or unit left to apply
        GDALRasterBandH band = GDALGetRasterBand(vrt, 1);
        GDALSetRasterScale(band, 1.0), GDALSetRasterOffset(band, 0.0), GDALSetRasterUnitType(band, "m");
      }
      return vrt;
    });
    facts[k].type = GDT_Float64;
    ++in_metres;
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
    const std::string from_datum = detail::vertical_datum_of(f.srs);
    // Heights move to another datum only when both name theirs: GDALWarp takes the heights of a
    // CRS without one as ellipsoidal, and shifted a 2D tile beside EGM96 ones by the geoid
    // (28 m here), where terralod reads such heights as the others' (EGM96 for most DEMs).
    const bool shift = !from_datum.empty() && !to_datum.empty() && from_datum != to_datum;
    bool shifted = false;  // whether the warp moves them (PROJ has the transformation)
    make(k, "warp", [&](const std::string& name, GDALDatasetH src) -> GDALDatasetH {
      const std::string dst = "DST_SRS=" + to_wkt;
      const char* const transform_options[] = {dst.c_str(), nullptr};
      void* transform = GDALCreateGenImgProjTransformer2(src, nullptr, const_cast<char**>(transform_options));
      if (transform == nullptr) return nullptr;
      double gt[6], extent[4];
      int w = 0, h = 0;
      const CPLErr rc =
          GDALSuggestedWarpOutput2(src, GDALGenImgProjTransform, transform, gt, &w, &h, extent, 0);
      if (shift) {  // the height 0 at its centre, as the warp shifts heights
        double px = 0.5 * GDALGetRasterXSize(src), py = 0.5 * GDALGetRasterYSize(src), pz = 0.0;
        int ok = 0;
        GDALGenImgProjTransform(transform, FALSE, 1, &px, &py, &pz, &ok);
        shifted = ok && pz != 0.0;
      }
      GDALDestroyGenImgProjTransformer(transform);
      if (rc != CE_None) return nullptr;
      // A footprint on the target's cells up to rounding (the same horizontal CRS, another
      // vertical one) is not widened by a cell of void: 1e-6 of a cell is rounding.
      const auto down = [](double cells) { return std::floor(cells + 1e-6); };
      const auto up = [](double cells) { return std::ceil(cells - 1e-6); };
      const double x0 = ox + down((extent[0] - ox) / rx) * rx, x1 = ox + up((extent[2] - ox) / rx) * rx;
      const double y0 = oy + down((extent[1] - oy) / ry) * ry, y1 = oy + up((extent[3] - oy) / ry) * ry;
      const std::vector<std::string> args = {"-of",
                                             "VRT",
                                             shift ? "-vshift" : "-novshift",
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
    if (from_datum != to_datum) ++datums[{from_datum, shifted}];
  }
  // One sample type, and one colour interpretation, which means nothing for heights but which
  // GDALBuildVRT also wants alike: an SRTM .hgt tile's band is Undefined, a GeoTIFF's Gray.
  GDALDataType common = types[0];
  bool mixed = false;
  for (GDALDataType t : types) mixed |= t != types[0];
  if (mixed || (floats && types[0] != GDT_Float32 && types[0] != GDT_Float64)) {
    common = GDT_Float32;
    for (GDALDataType t : types)
      if (!detail::fits_float32(t)) common = GDT_Float64;
  }
  const auto interpretation = [&](std::size_t k) {
    detail::QuietGdal quiet;
    GDALDatasetUniquePtr ds(GDALDataset::Open(absolute_source(out[k]).c_str(), GDAL_OF_RASTER));
    return ds && ds->GetRasterCount() > 0 ? ds->GetRasterBand(1)->GetColorInterpretation() : GCI_Undefined;
  };
  const std::string first_interpretation = lower(GDALGetColorInterpretationName(interpretation(0)));
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
  for (const auto& [key, n] : datums) {
    const auto& [from, shifted] = key;
    note +=
        "; heights of " + std::to_string(n) + (from.empty() ? " without a vertical datum" : " in " + from);
    if (to_datum.empty())
      note += " read unconverted (" + std::string(to.GetName() ? to.GetName() : "the mosaic's CRS") +
              " names no vertical datum)";
    else if (shifted)
      note += " converted to " + to_datum;
    else
      note += " read as " + to_datum + (from.empty() ? "" : " unconverted (PROJ has no transformation here)");
  }
  if (converted) note += "; " + std::to_string(converted) + " read as " + GDALGetDataTypeName(common);
  if (unalpha) note += "; " + std::to_string(unalpha) + " with its alpha band read as voids";
  if (in_metres)
    note += "; heights of " + std::to_string(in_metres) + " converted to metres (unit, scale, offset)";
  return out;
}

/// The first band of a VRT mosaic that GDALBuildVRT wrote, read from its XML (every band of such
/// a mosaic has the same sources); band() is nullptr when the file holds none.
class VrtBand {
 public:
  explicit VrtBand(const std::string& path) : root_(CPLParseXMLFile(path.c_str())) {
    const CPLXMLNode* dataset = root_ ? CPLGetXMLNode(root_, "=VRTDataset") : nullptr;
    for (CPLXMLNode* b = dataset ? dataset->psChild : nullptr; b && !band_; b = b->psNext)
      if (b->eType == CXT_Element && std::string(b->pszValue) == "VRTRasterBand") band_ = b;
  }
  ~VrtBand() {
    if (root_) CPLDestroyXMLNode(root_);
  }
  VrtBand(const VrtBand&) = delete;
  VrtBand& operator=(const VrtBand&) = delete;
  CPLXMLNode* band() const { return band_; }
  /// f(source element) for each of the band's sources, in the order of the mosaic's files.
  template <class F>
  void for_each_source(F&& f) const {
    for (CPLXMLNode* s = band_ ? band_->psChild : nullptr; s; s = s->psNext)
      if (s->eType == CXT_Element && CPLGetXMLNode(s, "DstRect")) f(s);
  }

 private:
  CPLXMLNode* root_;
  CPLXMLNode* band_ = nullptr;
};

/// Whether the sources of the VRT mosaic at `path` (GDALBuildVRT's, which it puts at the
/// mean sample spacing) are scaled: whether the inputs' spacings differ.
bool resamples(const std::string& path) {
  bool scaled = false;
  VrtBand(path).for_each_source([&](const CPLXMLNode* s) {
    const char* sw = CPLGetXMLValue(s, "SrcRect.xSize", nullptr);
    const char* dw = CPLGetXMLValue(s, "DstRect.xSize", nullptr);
    const char* sh = CPLGetXMLValue(s, "SrcRect.ySize", nullptr);
    const char* dh = CPLGetXMLValue(s, "DstRect.ySize", nullptr);
    if (sw && dw && sh && dh &&
        (std::abs(CPLAtof(sw) - CPLAtof(dw)) > 1e-6 * CPLAtof(dw) ||
         std::abs(CPLAtof(sh) - CPLAtof(dh)) > 1e-6 * CPLAtof(dh)))
      scaled = true;
  });
  return scaled;
}

/// Two sources of the VRT mosaic at `path` that GDALBuildVRT put on the same cells (the same
/// destination window), as their indices in its list of files; {-1, -1} when there are none.
/// Such files are two layers of one place (a tile's heights and its quality mask, or one tile
/// twice), not a mosaic: the later one would hide the other whole.
std::pair<int, int> same_cells(const std::string& path) {
  std::map<std::array<std::string, 4>, int> seen;
  std::pair<int, int> pair{-1, -1};
  int k = 0;
  VrtBand(path).for_each_source([&](const CPLXMLNode* s) {
    std::array<std::string, 4> cells;
    int i = 0;
    for (const char* field : {"DstRect.xOff", "DstRect.yOff", "DstRect.xSize", "DstRect.ySize"})
      cells[i++] = CPLGetXMLValue(s, field, "");
    if (const auto [at, fresh] = seen.emplace(cells, k); !fresh && pair.first < 0) pair = {at->second, k};
    ++k;
  });
  return pair;
}

/// Whether the files of the VRT mosaic at `path` disagree on their nodata value. GDALBuildVRT
/// gives the mosaic the first file's nodata value (or none) and paints each file without its
/// own nodata samples, so then a valid sample of one file that equals the mosaic's nodata value
/// reads as a void, and where the mosaic has none, another file's voids read as heights of 0.
bool nodata_differs(const std::string& path) {
  const VrtBand vrt(path);
  const auto value = [](const CPLXMLNode* node, const char* name) {
    const char* v = node ? CPLGetXMLValue(node, name, nullptr) : nullptr;
    return v ? std::optional<std::string>(v) : std::nullopt;
  };
  const std::optional<std::string> mosaic = value(vrt.band(), "NoDataValue");
  bool differs = false;
  vrt.for_each_source([&](const CPLXMLNode* s) { differs |= value(s, "NODATA") != mosaic; });
  return differs;
}

/// Whether the VRT mosaic at `path` holds floating-point samples (NaN can be its nodata value).
bool float_samples(const std::string& path) {
  const VrtBand vrt(path);
  const std::string type = vrt.band() ? CPLGetXMLValue(vrt.band(), "dataType", "") : "";
  return type == "Float32" || type == "Float64";
}

/// Gives the bands of the VRT mosaic at `path` the scale, offset and vertical unit of `file`'s
/// first band (GDALBuildVRT keeps none of them), so that read_dem makes its samples metres as it
/// does the file's.
void keep_height_scale(const std::string& path, const std::string& file) {
  detail::QuietGdal quiet;
  GDALDatasetUniquePtr from(GDALDataset::Open(file.c_str(), GDAL_OF_RASTER));
  GDALDatasetUniquePtr vrt(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_UPDATE));
  if (!from || !vrt)
    throw DemError(file,
                   "cannot give the mosaic its heights' unit (" + detail::gdal_message("GDAL failed") + ")");
  GDALRasterBand* band = from->GetRasterBand(1);
  int has_scale = 0, has_offset = 0;
  const double scale = band->GetScale(&has_scale), offset = band->GetOffset(&has_offset);
  for (int b = 1; b <= vrt->GetRasterCount(); ++b) {
    GDALRasterBand* to = vrt->GetRasterBand(b);
    if (to->GetColorInterpretation() == GCI_AlphaBand) continue;
    if (has_scale) to->SetScale(scale);
    if (has_offset) to->SetOffset(offset);
    to->SetUnitType(band->GetUnitType());
  }
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
  std::size_t quality_layers = 0, unsearched = 0;
  for (const std::string& in : inputs) {
    std::error_code ec;
    if (fs::is_directory(in, ec)) {
      std::size_t skipped = 0, subfolders = 0;
      const std::vector<std::string> found = folder_tiles(in, skipped, subfolders);
      if (found.empty())
        throw DemError(in, no_elevation_file("the folder and its subfolders hold", true, skipped));
      quality_layers += skipped, unsearched += subfolders;
      files.insert(files.end(), found.begin(), found.end());
      folder = in;
    } else if (!archive_prefix(in).empty() && fs::is_regular_file(in, ec)) {
      std::size_t skipped = 0;
      const std::vector<std::string> found = archive_tiles(in, skipped);
      if (found.empty()) throw DemError(in, no_elevation_file("the archive holds", false, skipped));
      quality_layers += skipped;
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
    detail::HeightScale heights;
    const bool alike = heights_alike(files, heights);
    if (!alike || !detail::build_vrt(path_, sources).empty()) {
      sources = made_alike(files, path_ + ".alike", made_, note);
      mosaic(sources);
    }
    // Files whose nodata values differ (or that have none beside files that have one): the
    // mosaic's nodata becomes NaN, which no file's heights can equal, on float samples.
    if (nodata_differs(path_)) {
      if (!float_samples(path_)) {  // made alike again, as floats: that note replaces the first one's
        note.clear();
        sources = made_alike(files, path_ + ".float", made_, note, /*floats=*/true);
      }
      args = {"-vrtnodata", "nan"};
      mosaic(sources);
      note += "; nodata values differ: voids kept as NaN";
    }
    // GDALBuildVRT puts files of different sample spacings on their mean spacing, which drops
    // detail from the finer ones: the finest is kept, the coarser files resampled bilinearly
    // (GDAL's default, nearest, would make them steps).
    if (resamples(path_)) {
      args.insert(args.end(), {"-resolution", "highest", "-r", "bilinear"});
      mosaic(sources);
      note += "; on the finest sample spacing, coarser files resampled bilinearly";
    }
    if (spans_half_the_earth(path_)) {
      const std::size_t before = made_.size();
      const std::vector<std::string> moved = across_antimeridian(sources, path_ + ".east", made_);
      if (made_.size() > before) mosaic(moved);
    }
    // Files whose heights are alike but not metres: the mosaic's bands say how, as the files do.
    if (alike && !heights.metres()) keep_height_scale(path_, files[0]);
    if (const auto [a, b] = same_cells(path_); a >= 0) {
      const std::string &first = files[std::size_t(a)], &second = files[std::size_t(b)];
      throw DemError(folder.empty() ? second : folder,
                     first + " and " + second +
                         " cover the same cells: a mosaic takes one elevation raster per place (one of "
                         "them may be another layer of the tile, such as a quality mask, or the same tile "
                         "twice); give the tiles to use with --input");
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
  if (quality_layers)
    note += "; " + std::to_string(quality_layers) + " quality layer" + (quality_layers == 1 ? "" : "s") +
            " beside the tiles left out (ASTER _num, Copernicus _EDM _FLM _HEM _WBM)";
  if (unsearched)
    note += "; " + std::to_string(unsearched) + (unsearched == 1 ? " subfolder" : " subfolders") +
            " not searched (a folder's own elevation files are its tiles; give a subfolder with --input to "
            "add it)";
  description_ += note;
}

DemInputs::~DemInputs() {
  if (owned_) VSIUnlink(path_.c_str());
  for (const std::string& s : made_) VSIUnlink(s.c_str());
}

}  // namespace terralod::blocks
