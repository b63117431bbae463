// A GeoTIFF (geographic, EPSG:4326, or in any EPSG CRS) written sample by sample, for tests of the
// DEM reader's frames and of the exporters. Header-only: the tests that include it link GDAL through
// terralod::blocks.
#pragma once

#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogr_spatialref.h>

#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <vector>

namespace terralod::test {

/// The WKT of the CRS EPSG:`epsg`.
inline std::string epsg_wkt(int epsg) {
  OGRSpatialReference srs;
  EXPECT_EQ(srs.importFromEPSG(epsg), OGRERR_NONE) << "EPSG:" << epsg;
  char* text = nullptr;
  srs.exportToWkt(&text);
  const std::string s = text != nullptr ? text : "";
  CPLFree(text);
  return s;
}

/// Writes `path`: cols x rows samples of `type` in the CRS EPSG:`epsg`, `step` CRS units apart,
/// the north-west sample's centre at (x0, y0), each sample height(x, y) (NaN: a void, the band's
/// nodata; -32768 for integer types).
inline void write_tiff(const std::string& path, int epsg, double x0, double y0, int cols, int rows,
                       double step, GDALDataType type, const std::function<double(double, double)>& height) {
  GDALAllRegister();
  GDALDatasetUniquePtr ds(
      GetGDALDriverManager()->GetDriverByName("GTiff")->Create(path.c_str(), cols, rows, 1, type, nullptr));
  ASSERT_TRUE(ds) << path;
  double gt[6] = {x0 - 0.5 * step, step, 0.0, y0 + 0.5 * step, 0.0, -step};
  ds->SetGeoTransform(gt);
  OGRSpatialReference srs;
  srs.importFromEPSG(epsg);
  ds->SetSpatialRef(&srs);
  const bool integer = GDALDataTypeIsInteger(type) != 0;
  const double nodata = integer ? -32768.0 : std::numeric_limits<double>::quiet_NaN();
  std::vector<double> z(std::size_t(cols) * std::size_t(rows));
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      const double h = height(x0 + c * step, y0 - r * step);
      z[std::size_t(r) * cols + c] = std::isnan(h) ? nodata : integer ? std::round(h) : h;
    }
  GDALRasterBand* band = ds->GetRasterBand(1);
  band->SetNoDataValue(nodata);
  ASSERT_EQ(band->RasterIO(GF_Write, 0, 0, cols, rows, z.data(), cols, rows, GDT_Float64, 0, 0), CE_None)
      << path;
}

/// Writes `path`: cols x rows Float64 samples `step` degrees apart, the north-west sample's centre
/// at (west, north) degrees, each sample height(lon, lat) (NaN: a void, the band's nodata).
inline void write_geographic_tiff(const std::string& path, double west, double north, int cols, int rows,
                                  double step, const std::function<double(double, double)>& height) {
  write_tiff(path, 4326, west, north, cols, rows, step, GDT_Float64, height);
}

}  // namespace terralod::test
