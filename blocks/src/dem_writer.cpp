// DEM writers (see dem_writer.hpp).
#include "terralod/blocks/dem_writer.hpp"

#include <gdal_priv.h>

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <vector>

#include "gdal_support.hpp"
#include "terralod/pm/atomic_file.hpp"
#include "terralod/pm/parallel.hpp"

namespace terralod::blocks {

namespace fs = std::filesystem;

constexpr std::int64_t kTileRows = 256;  // the GeoTIFF's tile height

struct GeoTiffWriter::Impl {
  std::string path, tmp;
  std::int64_t width = 0, height = 0;
  GDALDataset* ds = nullptr;
  bool committed = false;

  [[noreturn]] void fail(const std::string& what) {
    const std::string gdal = CPLGetLastErrorMsg();
    throw DemError(path, what + (gdal.empty() ? "" : " (" + gdal + ")"));
  }
};

namespace {

/// `horizontal` with the vertical datum `datum` (see the header's contract), or unchanged when
/// no datum is named or it has one already; false when GDAL cannot make the compound CRS.
bool add_vertical_datum(OGRSpatialReference& horizontal, const std::string& datum) {
  if (datum.empty() || horizontal.IsCompound() || horizontal.IsVertical() ||
      detail::has_ellipsoidal_height_axis(horizontal))
    return true;  // a 3D CRS has its heights' datum: the ellipsoid
  // The exporters' reading of the name (detail::vertical_crs); any other name, ellipsoidal ones
  // included, as a vertical CRS of that name, so that it reads back as written.
  const std::string crs = detail::vertical_crs(datum);
  OGRSpatialReference vertical;
  if (crs.rfind("EPSG:", 0) == 0 ? vertical.SetFromUserInput(crs.c_str()) != OGRERR_NONE
                                 : vertical.SetVertCS(datum.c_str(), datum.c_str()) != OGRERR_NONE)
    return false;
  OGRSpatialReference compound;
  const std::string name = std::string(horizontal.GetName() ? horizontal.GetName() : "unnamed") + " + " +
                           (vertical.GetName() ? vertical.GetName() : datum.c_str());
  if (compound.SetCompoundCS(name.c_str(), &horizontal, &vertical) != OGRERR_NONE) return false;
  horizontal = compound;
  return true;
}

}  // namespace

GeoTiffWriter::GeoTiffWriter(const std::string& path, std::int64_t width, std::int64_t height,
                             const pm::GridTransform& t, const std::string& crs_wkt,
                             const std::string& vertical_datum)
    : impl_(std::make_unique<Impl>()) {
  if (width < 1 || height < 1 || width > std::numeric_limits<int>::max() ||
      height > std::numeric_limits<int>::max())
    throw std::invalid_argument(path + ": a GeoTIFF of " + std::to_string(width) + " x " +
                                std::to_string(height) + " samples cannot be written");
  detail::register_gdal();
  Impl& m = *impl_;
  m.path = path, m.tmp = path + ".tmp.tif", m.width = width, m.height = height;
  GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("GTiff");
  if (!drv) throw DemError(path, "GDAL has no GTiff driver");
  char** opts = nullptr;
  opts = CSLSetNameValue(opts, "COMPRESS", "DEFLATE");
  opts = CSLSetNameValue(opts, "TILED", "YES");
  opts = CSLSetNameValue(opts, "BIGTIFF", "IF_SAFER");
  CPLErrorReset();
  m.ds = drv->Create(m.tmp.c_str(), int(width), int(height), 1, GDT_Float32, opts);
  CSLDestroy(opts);
  if (!m.ds) m.fail("cannot create the GeoTIFF");
  // Sample centres are at integer (col, row); GDAL's geotransform maps pixel corners.
  double gt[6] = {t.x0 - 0.5 * (t.xc + t.xr), t.xc, t.xr, t.y0 - 0.5 * (t.yc + t.yr), t.yc, t.yr};
  bool ok = m.ds->SetGeoTransform(gt) == CE_None;
  if (ok && !crs_wkt.empty()) {
    OGRSpatialReference srs;
    ok = srs.importFromWkt(crs_wkt.c_str()) == OGRERR_NONE && add_vertical_datum(srs, vertical_datum) &&
         m.ds->SetSpatialRef(&srs) == CE_None;
  }
  ok = ok && m.ds->GetRasterBand(1)->SetNoDataValue(std::numeric_limits<double>::quiet_NaN()) == CE_None;
  if (!ok) {
    GDALClose(m.ds);
    m.ds = nullptr;
    std::error_code ec;
    fs::remove(m.tmp, ec);
    m.fail("cannot set the GeoTIFF's geotransform, CRS or nodata");
  }
}

GeoTiffWriter::~GeoTiffWriter() {
  if (!impl_ || impl_->committed) return;
  if (impl_->ds) GDALClose(impl_->ds);
  std::error_code ec;
  fs::remove(impl_->tmp, ec);
}

void GeoTiffWriter::write_rows(std::int64_t row0, std::int64_t rows, const float* heights) {
  Impl& m = *impl_;
  if (m.committed || row0 < 0 || rows < 0 || row0 + rows > m.height)
    throw std::invalid_argument(m.path + ": rows " + std::to_string(row0) + " + " + std::to_string(rows) +
                                " outside the " + std::to_string(m.height) + " rows");
  if (rows == 0) return;
  CPLErrorReset();
  if (m.ds->GetRasterBand(1)->RasterIO(GF_Write, 0, int(row0), int(m.width), int(rows),
                                       const_cast<float*>(heights), int(m.width), int(rows), GDT_Float32, 0,
                                       0) != CE_None)
    m.fail("cannot write rows " + std::to_string(row0) + ".." + std::to_string(row0 + rows - 1));
  // GDAL keeps written tiles in its block cache (5% of the machine's memory by default): a
  // finished row of 256 x 256 tiles is flushed, so memory does not grow with the raster.
  if ((row0 + rows) % kTileRows == 0) m.ds->FlushCache(false);
}

void GeoTiffWriter::commit() {
  Impl& m = *impl_;
  if (m.committed) return;
  CPLErrorReset();
  GDALClose(m.ds);  // void in GDAL 3.6: a failure to flush shows as the last error
  const bool ok = CPLGetLastErrorType() < CE_Failure;
  m.ds = nullptr;
  std::error_code ec;
  if (!ok) {
    fs::remove(m.tmp, ec);
    m.fail("cannot finish the GeoTIFF");
  }
  pm::rename_into_place(m.tmp, m.path);
  m.committed = true;
}

void write_geotiff(const pm::Heightfield& hf, const std::string& path) {
  // In its CRS when the heightfield knows where its samples lie in it; else the metric frame
  // without a CRS (read back as metres).
  GeoTiffWriter w = hf.crs_transform ? GeoTiffWriter(path, hf.width(), hf.height(), *hf.crs_transform,
                                                     hf.crs_wkt, hf.vertical_datum)
                                     : GeoTiffWriter(path, hf.width(), hf.height(), hf.transform);
  std::vector<float> row(std::size_t(hf.width()));
  for (int r = 0; r < hf.height(); ++r) {
    for (int c = 0; c < hf.width(); ++c) {
      const std::size_t i = std::size_t(r) * std::size_t(hf.width()) + std::size_t(c);
      row[std::size_t(c)] = hf.valid(i) ? float(hf[i]) : std::numeric_limits<float>::quiet_NaN();
    }
    w.write_rows(r, 1, row.data());
  }
  w.commit();
}

void write_fractal_dem(const pm::FractalField& field, const std::string& path, int threads,
                       const std::function<void(double)>& progress) {
  const std::int64_t width = field.options().width, height = field.options().height;
  GeoTiffWriter w(path, width, height, field.transform());
  // Strips of 256 rows (the TIFF's tile height): each thread computes one, then they are written
  // in order, a round of strips at a time, so memory stays at one strip per thread.
  constexpr std::int64_t kStrip = kTileRows;
  const std::int64_t strips = (height + kStrip - 1) / kStrip;
  const std::size_t n = std::size_t(pm::thread_count(threads));
  std::vector<std::vector<float>> buffers(n, std::vector<float>(std::size_t(kStrip * width)));
  for (std::int64_t first = 0; first < strips; first += std::int64_t(n)) {
    const std::size_t round = std::size_t(std::min<std::int64_t>(std::int64_t(n), strips - first));
    pm::parallel_for(round, int(n), [&](std::size_t k) {
      const std::int64_t row0 = (first + std::int64_t(k)) * kStrip;
      const std::int64_t rows = std::min(kStrip, height - row0);
      float* out = buffers[k].data();
      for (std::int64_t r = 0; r < rows; ++r)
        for (std::int64_t c = 0; c < width; ++c) out[r * width + c] = float(field.at(c, row0 + r));
    });
    for (std::size_t k = 0; k < round; ++k) {
      const std::int64_t row0 = (first + std::int64_t(k)) * kStrip;
      w.write_rows(row0, std::min(kStrip, height - row0), buffers[k].data());
    }
    if (progress) progress(double(first + std::int64_t(round)) / double(strips));
  }
  w.commit();
}

MosaicReport write_mirror_mosaic(const std::string& source, int tiles_x, int tiles_y,
                                 const std::string& out_dir, const std::function<void(double)>& progress) {
  if (tiles_x < 1 || tiles_y < 1)
    throw std::invalid_argument(out_dir + ": a mosaic needs at least 1 x 1 tiles, not " +
                                std::to_string(tiles_x) + " x " + std::to_string(tiles_y));
  DemOptions keep;
  keep.fill_voids = false;  // the mosaic carries the source's voids; the build fills them
  const pm::Heightfield hf = read_dem(source, keep);
  const pm::GridTransform t = hf.crs_transform.value_or(hf.transform);
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  if (ec) throw DemError(out_dir, "cannot create the mosaic folder: " + ec.message());
  const int w = hf.width(), h = hf.height();
  std::vector<std::string> names;
  std::vector<float> tile(std::size_t(w) * std::size_t(h));
  for (int j = 0; j < tiles_y; ++j)
    for (int i = 0; i < tiles_x; ++i) {
      for (int r = 0; r < h; ++r)
        for (int c = 0; c < w; ++c) {
          const int sc = i % 2 ? w - 1 - c : c, sr = j % 2 ? h - 1 - r : r;
          const std::size_t s = std::size_t(sr) * std::size_t(w) + std::size_t(sc);
          tile[std::size_t(r) * std::size_t(w) + std::size_t(c)] =
              hf.valid(s) ? float(hf[s]) : std::numeric_limits<float>::quiet_NaN();
        }
      // Sample (0, 0) of tile (i, j) is sample (i (w - 1), j (h - 1)) of the mosaic.
      pm::GridTransform ti = t;
      const auto [x0, y0] = t.to_world(double(i) * (w - 1), double(j) * (h - 1));
      ti.x0 = x0, ti.y0 = y0;
      const std::string name =
          (fs::path(out_dir) / ("tile_" + std::to_string(j) + "_" + std::to_string(i) + ".tif")).string();
      GeoTiffWriter out(name, w, h, ti, hf.crs_wkt, hf.vertical_datum);
      out.write_rows(0, h, tile.data());
      out.commit();
      names.push_back(name);
      if (progress) progress(double(names.size()) / double(tiles_x * tiles_y));
    }
  MosaicReport report;
  report.vrt = (fs::path(out_dir) / "mosaic.vrt").string();
  report.width = std::int64_t(tiles_x) * (w - 1) + 1;
  report.height = std::int64_t(tiles_y) * (h - 1) + 1;
  report.tiles = tiles_x * tiles_y;
  const std::string tmp = report.vrt + ".tmp.vrt";
  if (const std::string why = detail::build_vrt(tmp, names); !why.empty())
    throw DemError(report.vrt, "cannot build the VRT (" + why + ")");
  pm::rename_into_place(tmp, report.vrt);
  return report;
}

}  // namespace terralod::blocks
