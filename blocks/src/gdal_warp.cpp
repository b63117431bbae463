// One GDAL warp of a height grid between CRSs (see gdal_warp.hpp).
#include "gdal_warp.hpp"

#include <gdal_priv.h>
#include <gdal_utils.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <cstdio>
#include <exception>
#include <limits>
#include <memory>
#include <mutex>

#include "gdal_support.hpp"

namespace terralod::blocks::detail {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// A WarpSource as a GDAL raster of one Float64 band whose nodata is NaN. The warp reads its
/// source windows through the band's IRasterIO, which reads them from WarpSource::read
/// directly: no GDAL block cache holds them. A reader's exception is kept (failure()) and GDAL
/// told of a failed read, which stops the warp.
class SourceDataset final : public GDALDataset {
 public:
  SourceDataset(const WarpSource& src, const OGRSpatialReference& srs);

  CPLErr GetGeoTransform(double* gt) override {
    std::copy(src_.gt.begin(), src_.gt.end(), gt);
    return CE_None;
  }
  const OGRSpatialReference* GetSpatialRef() const override { return &srs_; }

  /// The window into out (cols x rows, row-major); false when the reader failed (then and
  /// after: a failed reader is not asked again).
  bool read(int col0, int row0, int cols, int rows, double* out) {
    std::lock_guard lock(mutex_);
    if (failure_) return false;
    try {
      src_.read(col0, row0, cols, rows, out);
      return true;
    } catch (...) {
      failure_ = std::current_exception();
      return false;
    }
  }
  /// What the reader threw, or nullptr.
  std::exception_ptr failure() {
    std::lock_guard lock(mutex_);
    return failure_;
  }

 private:
  const WarpSource& src_;
  OGRSpatialReference srs_;
  std::mutex mutex_;  // the warp's I/O and computing threads may both read
  std::exception_ptr failure_;
};

class SourceBand final : public GDALRasterBand {
 public:
  explicit SourceBand(SourceDataset* ds) : ds_(ds) {
    poDS = ds;
    nBand = 1;
    eDataType = GDT_Float64;
    nRasterXSize = ds->GetRasterXSize();
    nRasterYSize = ds->GetRasterYSize();
    nBlockXSize = std::min(nRasterXSize, 512);
    nBlockYSize = std::min(nRasterYSize, 512);
  }
  double GetNoDataValue(int* ok) override {
    if (ok != nullptr) *ok = TRUE;
    return kNaN;
  }

 protected:
  // Only for callers that read by blocks (the warp does not): the block's samples, NaN past the
  // raster's edge.
  CPLErr IReadBlock(int bx, int by, void* data) override {
    const int c0 = bx * nBlockXSize, r0 = by * nBlockYSize;
    const int cols = std::min(nBlockXSize, nRasterXSize - c0),
              rows = std::min(nBlockYSize, nRasterYSize - r0);
    std::vector<double> window(std::size_t(cols) * std::size_t(rows));
    if (!ds_->read(c0, r0, cols, rows, window.data())) return CE_Failure;
    double* out = static_cast<double*>(data);
    std::fill(out, out + std::size_t(nBlockXSize) * std::size_t(nBlockYSize), kNaN);
    for (int r = 0; r < rows; ++r)
      std::copy_n(window.data() + std::size_t(r) * std::size_t(cols), cols,
                  out + std::size_t(r) * std::size_t(nBlockXSize));
    return CE_None;
  }
  CPLErr IRasterIO(GDALRWFlag rw, int x, int y, int cols, int rows, void* data, int buf_cols, int buf_rows,
                   GDALDataType type, GSpacing pixel_space, GSpacing line_space,
                   GDALRasterIOExtraArg* extra) override {
    if (rw != GF_Read) return CE_Failure;
    if (buf_cols != cols || buf_rows != rows)  // resampled: through the blocks
      return GDALRasterBand::IRasterIO(rw, x, y, cols, rows, data, buf_cols, buf_rows, type, pixel_space,
                                       line_space, extra);
    if (type == GDT_Float64 && pixel_space == GSpacing(sizeof(double)) &&
        line_space == GSpacing(cols) * pixel_space)  // the warp's own source buffer: read into it
      return ds_->read(x, y, cols, rows, static_cast<double*>(data)) ? CE_None : CE_Failure;
    std::vector<double> window(std::size_t(cols) * std::size_t(rows));
    if (!ds_->read(x, y, cols, rows, window.data())) return CE_Failure;
    for (int r = 0; r < rows; ++r)
      GDALCopyWords64(window.data() + std::size_t(r) * std::size_t(cols), GDT_Float64, sizeof(double),
                      static_cast<GByte*>(data) + r * line_space, type, int(pixel_space), cols);
    return CE_None;
  }

 private:
  SourceDataset* ds_;
};

SourceDataset::SourceDataset(const WarpSource& src, const OGRSpatialReference& srs) : src_(src), srs_(srs) {
  nRasterXSize = src.width;
  nRasterYSize = src.height;
  SetBand(1, new SourceBand(this));
}

/// The grid gdalwarp chooses for `source` with its arguments `args` (-t_srs and the rest): the
/// size and geotransform of a warped VRT, which reads and computes nothing until it is read.
bool suggested_grid(GDALDatasetH source, const std::vector<std::string>& args, WarpGrid& grid) {
  std::vector<std::string> vrt_args = args;
  vrt_args.insert(vrt_args.begin(), {"-of", "VRT"});
  GDALWarpAppOptions* options = gdal_options(vrt_args, GDALWarpAppOptionsNew);
  if (options == nullptr) return false;
  int usage_error = 0;
  GDALDatasetH vrt = GDALWarp("", nullptr, 1, &source, options, &usage_error);
  GDALWarpAppOptionsFree(options);
  if (vrt == nullptr) return false;
  grid.width = GDALGetRasterXSize(vrt);
  grid.height = GDALGetRasterYSize(vrt);
  double gt[6];
  GDALGetGeoTransform(vrt, gt);
  std::copy(gt, gt + 6, grid.gt.begin());
  GDALClose(vrt);
  return true;
}

}  // namespace

WarpGrid warp_grid(const WarpSource& src, const std::string& src_wkt, const std::string& dst_wkt,
                   std::string& error, const WarpGrid* layout) {
  register_gdal();
  QuietGdal quiet;
  error.clear();
  // Reference-counted, as GDAL's datasets are (a VRT made of it may hold a reference): this
  // function's reference is released when it returns, and the last one deletes it.
  OGRSpatialReference srs;  // any CRS text GDAL takes, as GDALDataset::SetProjection did
  srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  if (srs.SetFromUserInput(src_wkt.c_str()) != OGRERR_NONE) {
    error = "GDAL does not understand the source's coordinate reference system";
    return {};
  }
  auto* in = new SourceDataset(src, srs);
  struct Release {
    SourceDataset* ds;
    ~Release() { ds->ReleaseRef(); }
  } release{in};
  GDALDatasetH source = GDALDataset::ToHandle(in);

  // gdalwarp -t_srs DST -r bilinear -et 0 -srcnodata nan -dstnodata nan -wo NUM_THREADS=ALL_CPUS
  // -multi -novshift -wm CHUNK -wo XSCALE=X -wo YSCALE=Y: exact transformations (-et 0; the
  // approximate transformer at 0.125 pixel halved the warp of N44W072, 0.7 s -> 0.3 s, for up to
  // 0.125 pixel of displacement), on every core; heights as they are (-novshift: GDALWarp shifts a
  // source that names its vertical datum to ellipsoidal heights by itself, and the exporters
  // convert them from that datum after). Chunks of 8 MiB: the source is read a chunk's window at
  // a time (a 3690 x 3613 terrain's export peaked at 444 MB with the source whole, 288 MB in
  // GDAL's default chunks of 64 MiB, 195 MB in these, in the same time). XSCALE, YSCALE: the
  // output's samples per source sample over the whole grid (about what GDAL takes for a warp in
  // one chunk), the same for every chunk. GDAL otherwise takes each chunk's own ratio of output to
  // source window, and below 1 widens the bilinear kernel as a downsampling needs: corner chunks,
  // where the source fills little of the output's box, came out smoothed (by up to 2.7 m on that
  // terrain in chunks of 8 MiB) and the grid depended on the chunking.
  // The grid is chosen with -t_srs first; the warp then writes into a raster of that grid.
  const std::vector<std::string> common = {"-r",     "bilinear",
                                           "-et",    "0",
                                           "-wo",    "NUM_THREADS=ALL_CPUS",
                                           "-multi", "-novshift",
                                           "-wm",    std::to_string(src.chunk_mib)};
  WarpGrid w;
  if (layout != nullptr) {
    w.width = layout->width, w.height = layout->height, w.gt = layout->gt;
  } else {
    std::vector<std::string> layout_args = common;
    layout_args.insert(layout_args.end(), {"-t_srs", dst_wkt});
    if (!suggested_grid(source, layout_args, w)) {
      error = gdal_message("GDAL could not find a grid to warp to");
      return {};
    }
  }
  // The warp writes into w.z (a MEM raster over it): no copy of the output.
  w.z.assign(std::size_t(w.width) * std::size_t(w.height), std::numeric_limits<float>::quiet_NaN());
  GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
  std::unique_ptr<GDALDataset> out(mem->Create("", w.width, w.height, 0, GDT_Float32, nullptr));
  char pointer[64];
  std::snprintf(pointer, sizeof pointer, "DATAPOINTER=%p", static_cast<void*>(w.z.data()));
  char* band_options[] = {pointer, nullptr};
  if (!out || out->AddBand(GDT_Float32, band_options) != CE_None) {
    error = "GDAL could not make an in-memory raster to warp into";
    return {};
  }
  double gt[6] = {w.gt[0], w.gt[1], w.gt[2], w.gt[3], w.gt[4], w.gt[5]};
  out->SetGeoTransform(gt);
  out->SetProjection(dst_wkt.c_str());
  out->GetRasterBand(1)->SetNoDataValue(kNaN);
  std::vector<std::string> warp_args = common;
  warp_args.insert(warp_args.end(),
                   {"-srcnodata", "nan", "-dstnodata", "nan", "-wo",
                    "XSCALE=" + gdal_number(layout ? 1.0 : double(w.width) / double(src.width)), "-wo",
                    "YSCALE=" + gdal_number(layout ? 1.0 : double(w.height) / double(src.height))});
  GDALWarpAppOptions* options = gdal_options(warp_args, GDALWarpAppOptionsNew);
  if (options == nullptr) {
    error = gdal_message("GDAL rejected the warp options");
    return {};
  }
  int usage_error = 0;
  GDALDatasetH done = GDALWarp(nullptr, GDALDataset::ToHandle(out.get()), 1, &source, options, &usage_error);
  GDALWarpAppOptionsFree(options);
  if (const std::exception_ptr failure = in->failure()) std::rethrow_exception(failure);
  if (done == nullptr) {
    error = gdal_message("GDAL could not warp the grid");
    return {};
  }
  return w;
}

}  // namespace terralod::blocks::detail
