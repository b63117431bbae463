// A georeferenced image warped into a terrain's world frame (image_warp.hpp).
#include "terralod/blocks/image_warp.hpp"

#include <gdal_priv.h>
#include <gdal_utils.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
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

BandRange whole_range(GDALDataType type) {
  return type_range(GDALGetDataTypeSizeBits(type), GDALDataTypeIsSigned(type) != 0,
                    GDALDataTypeIsFloating(type) != 0);
}

// One colour band's histogram over its valid pixels (GDAL's mask: nodata, alpha), cut at
// `percent` at each end (exact_histogram's bins, or 65,536 over the exact minimum..maximum
// after one more pass).
BandRange band_cut(GDALRasterBand& band, double percent, const std::string& image,
                   const std::function<void(double)>& progress) {
  const GDALDataType type = band.GetRasterDataType();
  const auto cannot = [&](const std::string& why) {
    return ImageWarpError(image + ": cannot read band " + std::to_string(band.GetBand()) +
                          " for its stretch (" + detail::gdal_message(why) + ")");
  };
  std::optional<BandHistogram> exact = exact_histogram(
      GDALGetDataTypeSizeBits(type), GDALDataTypeIsSigned(type) != 0, GDALDataTypeIsFloating(type) != 0);
  if (!exact) {
    double mm[2] = {0, 0};
    if (band.ComputeRasterMinMax(FALSE, mm) != CE_None) return {};  // no valid pixel
    exact.emplace(mm[0], mm[1], 65536);
  }
  BandHistogram& hist = *exact;
  GDALRasterBand* mask = (band.GetMaskFlags() & GMF_ALL_VALID) != 0 ? nullptr : band.GetMaskBand();
  const int w = band.GetXSize(), h = band.GetYSize();
  const int rows = std::max(1, (1 << 20) / std::max(w, 1));
  std::vector<double> values;
  std::vector<std::uint8_t> valid;
  for (int y = 0; y < h; y += rows) {
    const int n = std::min(rows, h - y);
    values.resize(std::size_t(w) * std::size_t(n));
    if (band.RasterIO(GF_Read, 0, y, w, n, values.data(), w, n, GDT_Float64, 0, 0) != CE_None)
      throw cannot("RasterIO failed");
    if (mask) {
      valid.resize(values.size());
      if (mask->RasterIO(GF_Read, 0, y, w, n, valid.data(), w, n, GDT_Byte, 0, 0) != CE_None)
        throw cannot("its mask cannot be read");
    }
    for (std::size_t i = 0; i < values.size(); ++i)
      if (!mask || valid[i] != 0) hist.add(values[i]);
    if (progress) progress(double(y + n) / double(h));
  }
  return hist.cut(percent);
}

// The ranges the colour bands (R, G, B: `colour`, 1-based) are drawn from, as
// image_stretch.hpp says; empty when the bands are 8-bit and shown as they are, or the image
// is drawn through its colour table.
std::vector<BandRange> band_ranges(GDALDataset& src, const std::vector<int>& colour, const StretchOptions& s,
                                   const std::string& image, const std::function<void(double)>& progress) {
  bool deep = false;
  for (const int b : colour) deep = deep || src.GetRasterBand(b)->GetRasterDataType() != GDT_Byte;
  if (src.GetRasterCount() == 1 && src.GetRasterBand(1)->GetColorTable() != nullptr) return {};
  const StretchStep step = stretch_step(s, deep);
  if (step == StretchStep::AsIs) return {};
  std::vector<BandRange> out(colour.size());
  for (std::size_t k = 0; k < colour.size(); ++k) {
    GDALRasterBand& band = *src.GetRasterBand(colour[k]);
    if (k > 0 && colour[k] == colour[k - 1]) {
      out[k] = out[k - 1];  // grey: one band three times
    } else if (step == StretchStep::Fixed) {
      out[k] = fixed_range(s, whole_range(band.GetRasterDataType()));
    } else {
      const auto part = [&, k](double f) {
        if (progress) progress((double(k) + f) / double(colour.size()));
      };
      out[k] = band_cut(band, s.cut_percent, image, part);
    }
  }
  return out;
}

}  // namespace

std::optional<WorldImage> warp_image_to_terrain(const std::string& image, const BlockDatabase& db,
                                                const std::string& out,
                                                const std::function<void(double)>& progress,
                                                const StretchOptions& stretch) {
  detail::register_gdal();
  detail::QuietGdal quiet;
  const detail::CacheCap cache;  // the histograms and the warp read the whole image
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
  // The rule of render/src/image_channels.hpp: a band is alpha only when it says so (a fourth
  // band is often near infrared); colour is the first three other bands, or the first as grey.
  const int bands = src->GetRasterCount();
  int alpha = 0;  // 1-based; 0: none
  for (int b = 1; b <= bands && alpha == 0; ++b)
    if (src->GetRasterBand(b)->GetColorInterpretation() == GCI_AlphaBand) alpha = b;
  std::vector<int> colour;
  for (int b = 1; b <= bands && colour.size() < 3; ++b)
    if (b != alpha) colour.push_back(b);
  if (colour.empty()) throw fail("has an alpha band only; a texture needs colour or grey");
  if (colour.size() < 3) colour.assign(3, colour[0]);
  // Bands deeper than 8 bits (and any band when asked) are stretched to 0..255 (image_stretch.hpp).
  const auto progress_from = [&](double a, double b) {
    return [&progress, a, b](double f) {
      if (progress) progress(a + (b - a) * f);
    };
  };
  WorldImage r;
  r.stretched = band_ranges(*src, colour, stretch, image, progress_from(0.0, 0.3));
  const bool rescale = !r.stretched.empty();
  std::vector<std::string> layout;  // gdal_translate arguments, empty: as it is (RGB, RGBA)
  bool mask_alpha = false;          // the alpha is GDAL's mask of the first colour band
  if (rescale) {
    // Three colour bands scaled to bytes (-scale_N counts the output's bands), and an alpha:
    // the image's own, scaled from its type's range, or GDAL's mask of the first colour band
    // (its nodata), which would not survive the bytes.
    mask_alpha = alpha == 0 && (src->GetRasterBand(colour[0])->GetMaskFlags() & GMF_ALL_VALID) == 0;
    layout = {"-ot", "Byte", "-a_nodata", "none"};
    for (int k = 0; k < 3; ++k) {
      const BandRange& br = r.stretched[std::size_t(k)];
      layout.insert(layout.end(),
                    {"-b", std::to_string(colour[std::size_t(k)]), "-scale_" + std::to_string(k + 1),
                     detail::gdal_number(br.lo), detail::gdal_number(br.hi), "0", "255"});
    }
    if (alpha != 0) {
      const BandRange ar = whole_range(src->GetRasterBand(alpha)->GetRasterDataType());
      layout.insert(layout.end(), {"-b", std::to_string(alpha), "-scale_4", detail::gdal_number(ar.lo),
                                   detail::gdal_number(ar.hi), "0", "255"});
    } else if (mask_alpha) {
      layout.insert(layout.end(), {"-b", "mask," + std::to_string(colour[0])});
    }
    layout.insert(layout.end(), {"-colorinterp", alpha != 0 ? "red,green,blue,alpha" : "red,green,blue"});
    if (mask_alpha) alpha = 4;
  } else if (bands == 1 && src->GetRasterBand(1)->GetColorTable() != nullptr) {
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
    // gdal_translate names no mask band's colour (its -colorinterp skips them).
    if (mask_alpha) expanded->GetRasterBand(4)->SetColorInterpretation(GCI_AlphaBand);
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

  // The warp, written beside `out` and renamed into place; deflated at the fastest level (a
  // temporary of 'texture add': an 8000 x 8000 image's add took 16.2-17.0 s at GDAL's default
  // level, 14.6-14.8 s so).
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
                                   "ZLEVEL=1",
                                   "-co",
                                   "BIGTIFF=IF_SAFER",
                                   "-multi",
                                   "-wo",
                                   "NUM_THREADS=ALL_CPUS",
                                   "-overwrite"};
  if (!alpha) args.push_back("-dstalpha");  // else the source's alpha becomes the output's
  GDALWarpAppOptions* o = detail::gdal_options(args, GDALWarpAppOptionsNew);
  const std::function<void(double)> warp_progress = progress_from(rescale ? 0.3 : 0.0, 1.0);
  if (o)
    GDALWarpAppOptionsSetProgress(o, progress_of, const_cast<std::function<void(double)>*>(&warp_progress));
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
