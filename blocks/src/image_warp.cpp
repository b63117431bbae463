// A georeferenced image warped into a terrain's world frame (image_warp.hpp).
#include "terralod/blocks/image_warp.hpp"

#include <gdal_priv.h>
#include <gdal_utils.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "gdal_support.hpp"
#include "terralod/pm/atomic_file.hpp"

namespace terralod::blocks {
namespace {

struct Box {
  double minx = std::numeric_limits<double>::infinity(), miny = minx;
  double maxx = -std::numeric_limits<double>::infinity(), maxy = maxx;
  void add(double x, double y) {
    minx = std::min(minx, x), miny = std::min(miny, y), maxx = std::max(maxx, x), maxy = std::max(maxy, y);
  }
  bool empty() const { return !(minx < maxx && miny < maxy); }
};

int progress_of(double done, const char*, void* data) {
  const auto* f = static_cast<const std::function<void(double)>*>(data);
  if (*f) (*f)(std::clamp(done, 0.0, 1.0));
  return 1;
}

}  // namespace

std::optional<WorldImage> warp_image_to_terrain(const std::string& image, const BlockDatabase& db,
                                                const std::string& out,
                                                const std::function<void(double)>& progress) {
  detail::register_gdal();
  detail::QuietGdal quiet;
  const auto fail = [&](const std::string& problem) { return ImageWarpError(image + ": " + problem); };
  GDALDatasetUniquePtr src(GDALDataset::Open(image.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  if (!src) return std::nullopt;  // not a raster GDAL reads: OpenImageIO may still read it
  // Placed by ground control points alone (a scanned map): north-up first, transparent outside
  // its footprint. It was read as an ungeoreferenced picture and stretched over the terrain.
  // GDAL's warp keeps no colour table: a colour-indexed scan would come out as grey indices.
  if (src->GetGCPCount() >= 3 && src->GetRasterCount() > 0 &&
      src->GetRasterBand(1)->GetColorTable() != nullptr)
    throw fail(
        "is a colour-indexed image placed by ground control points, which the warp north-up would turn "
        "grey; give its colours first (gdal_translate -expand rgb)");
  int gcps = 0;
  src = detail::north_up(std::move(src), {"-r", "bilinear", "-dstalpha"}, gcps);
  if (!src)
    throw fail("is placed by ground control points that GDAL cannot warp north-up (" +
               detail::gdal_message("GDALWarp failed") + ")");
  double gt[6];
  const OGRSpatialReference* image_srs = src->GetSpatialRef();
  if (src->GetGeoTransform(gt) != CE_None || image_srs == nullptr || image_srs->IsEmpty())
    return std::nullopt;

  const DatabaseInfo& info = db.info();
  const std::optional<Georeference> geo = db.georeference();
  if (info.crs_wkt.empty() || !geo)
    throw fail("is georeferenced, but the terrain " + db.path() +
               " has no CRS, so it cannot be placed on it (give --georef, or build the terrain from a "
               "georeferenced DEM)");
  const pm::GridTransform& ct = geo->crs_transform;
  const pm::GridTransform& wt = info.transform;
  if (ct.xr != 0.0 || ct.yc != 0.0 || wt.xr != 0.0 || wt.yc != 0.0)
    throw fail("the terrain " + db.path() +
               " has a rotated frame, so a box of its CRS is no box of its world (give --georef)");

  // The bands as RGB(A) bytes, through an in-memory VRT when they are not so already.
  const int bands = src->GetRasterCount();
  for (int b = 1; b <= bands; ++b)
    if (src->GetRasterBand(b)->GetRasterDataType() != GDT_Byte)
      throw fail(std::string("is georeferenced but its bands are ") +
                 GDALGetDataTypeName(src->GetRasterBand(1)->GetRasterDataType()) +
                 "; texture layers warp 8-bit images (gdal_translate -ot Byte -scale makes one)");
  // The rule of render/src/image_channels.hpp: a band is alpha only when it says so (a fourth
  // band is often near infrared); colour is the first three other bands, or the first as grey.
  int alpha = 0;  // 1-based; 0: none
  for (int b = 1; b <= bands && alpha == 0; ++b)
    if (src->GetRasterBand(b)->GetColorInterpretation() == GCI_AlphaBand) alpha = b;
  std::vector<int> colour;
  for (int b = 1; b <= bands && colour.size() < 3; ++b)
    if (b != alpha) colour.push_back(b);
  if (colour.empty()) throw fail("has an alpha band only; a texture needs colour or grey");
  if (colour.size() < 3) colour.assign(3, colour[0]);
  std::vector<std::string> layout;  // gdal_translate arguments, empty: as it is (RGB, RGBA)
  if (bands == 1 && src->GetRasterBand(1)->GetColorTable() != nullptr) {
    layout = {"-expand", "rgb"};
  } else if (!((bands == 3 && alpha == 0) || (bands == 4 && alpha == 4))) {
    for (const int b : colour) layout.insert(layout.end(), {"-b", std::to_string(b)});
    if (alpha != 0) layout.insert(layout.end(), {"-b", std::to_string(alpha)});
    layout.insert(layout.end(), {"-colorinterp", alpha != 0 ? "red,green,blue,alpha" : "red,green,blue"});
  }
  static std::atomic<int> serial{0};
  const std::string rgb = "/vsimem/terralod_image_" + std::to_string(serial++) + ".vrt";
  struct Unlink {
    std::string path;
    ~Unlink() { VSIUnlink(path.c_str()); }
  } unlink_rgb{rgb};
  GDALDatasetH input = GDALDataset::ToHandle(src.get());
  GDALDatasetUniquePtr expanded;
  if (!layout.empty()) {
    std::vector<std::string> args = {"-of", "VRT"};
    args.insert(args.end(), layout.begin(), layout.end());
    GDALTranslateOptions* o = detail::gdal_options(args, GDALTranslateOptionsNew);
    expanded.reset(GDALDataset::FromHandle(o ? GDALTranslate(rgb.c_str(), input, o, nullptr) : nullptr));
    GDALTranslateOptionsFree(o);
    if (!expanded)
      throw fail("cannot read its bands as RGB (" + detail::gdal_message("GDALTranslate failed") + ")");
    input = GDALDataset::ToHandle(expanded.get());
  }

  // The image's footprint in the terrain's CRS (points along its edges), and the terrain's.
  OGRSpatialReference from(*image_srs), to;
  from.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  if (to.importFromWkt(info.crs_wkt.c_str()) != OGRERR_NONE)
    throw DatabaseError(db.path(), "the terrain's CRS is not readable WKT");
  to.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> transform(OGRCreateCoordinateTransformation(&from, &to));
  if (!transform)
    throw fail("no transformation from its CRS to the terrain's (" + detail::gdal_message("PROJ found none") +
               ")");
  const int w = src->GetRasterXSize(), h = src->GetRasterYSize();
  std::vector<double> xs, ys;
  for (int k = 0; k <= 64; ++k) {
    const double f = k / 64.0;
    for (const auto& [c, r] : {std::pair{f * w, 0.0}, {f * w, double(h)}, {0.0, f * h}, {double(w), f * h}}) {
      xs.push_back(gt[0] + c * gt[1] + r * gt[2]);
      ys.push_back(gt[3] + c * gt[4] + r * gt[5]);
    }
  }
  std::vector<int> ok(xs.size(), 0);
  transform->Transform(int(xs.size()), xs.data(), ys.data(), nullptr, ok.data());
  Box footprint, terrain;
  for (std::size_t i = 0; i < xs.size(); ++i)
    if (ok[i] && std::isfinite(xs[i]) && std::isfinite(ys[i])) footprint.add(xs[i], ys[i]);
  for (const auto& [c, r] : {std::pair{-0.5, -0.5}, {info.grid_width - 0.5, info.grid_height - 0.5}}) {
    const auto [x, y] = ct.to_world(c, r);
    terrain.add(x, y);
  }
  Box cut{std::max(footprint.minx, terrain.minx), std::max(footprint.miny, terrain.miny),
          std::min(footprint.maxx, terrain.maxx), std::min(footprint.maxy, terrain.maxy)};
  if (footprint.empty() || cut.empty()) throw fail("does not overlap the terrain of " + db.path());

  // The warp, written beside `out` and renamed into place.
  const std::string tmp = out + ".tmp";
  std::vector<std::string> args = {"-of",
                                   "GTiff",
                                   "-t_srs",
                                   info.crs_wkt,
                                   "-te",
                                   detail::gdal_number(cut.minx),
                                   detail::gdal_number(cut.miny),
                                   detail::gdal_number(cut.maxx),
                                   detail::gdal_number(cut.maxy),
                                   "-r",
                                   "bilinear",
                                   "-co",
                                   "TILED=YES",
                                   "-co",
                                   "COMPRESS=DEFLATE",
                                   "-co",
                                   "BIGTIFF=IF_SAFER",
                                   "-multi",
                                   "-wo",
                                   "NUM_THREADS=ALL_CPUS",
                                   "-overwrite"};
  if (!alpha) args.push_back("-dstalpha");  // else the source's alpha becomes the output's
  GDALWarpAppOptions* o = detail::gdal_options(args, GDALWarpAppOptionsNew);
  if (o) GDALWarpAppOptionsSetProgress(o, progress_of, const_cast<std::function<void(double)>*>(&progress));
  int usage = 0;
  GDALDatasetUniquePtr warped(
      GDALDataset::FromHandle(o ? GDALWarp(tmp.c_str(), nullptr, 1, &input, o, &usage) : nullptr));
  GDALWarpAppOptionsFree(o);
  if (!warped) {
    VSIUnlink(tmp.c_str());
    throw fail("cannot be warped to the terrain's CRS (" + detail::gdal_message("GDALWarp failed") + ")");
  }
  double wgt[6];
  warped->GetGeoTransform(wgt);
  WorldImage r;
  r.width = warped->GetRasterXSize(), r.height = warped->GetRasterYSize();
  warped.reset();  // flushed and closed
  pm::rename_into_place(tmp, out);

  // Its corners: CRS -> terrain samples -> world (both transforms north-up: a box stays a box).
  Box world;
  for (const auto& [x, y] :
       {std::pair{wgt[0], wgt[3]}, {wgt[0] + r.width * wgt[1], wgt[3] + r.height * wgt[5]}}) {
    const double col = (x - ct.x0) / ct.xc, row = (y - ct.y0) / ct.yr;
    const auto [wx, wy] = wt.to_world(col, row);
    world.add(wx, wy);
  }
  r.minx = world.minx, r.miny = world.miny, r.maxx = world.maxx, r.maxy = world.maxy;
  return r;
}

}  // namespace terralod::blocks
