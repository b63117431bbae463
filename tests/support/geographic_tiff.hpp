// A geographic (EPSG:4326) GeoTIFF written sample by sample, for tests of the DEM reader's frames
// and of the exporters. Header-only: the tests that include it link GDAL through terralod::blocks.
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

/// Writes `path`: cols x rows Float64 samples `step` degrees apart, the north-west sample's centre
/// at (west, north) degrees, each sample height(lon, lat) (NaN: a void, the band's nodata).
inline void write_geographic_tiff(const std::string& path, double west, double north, int cols, int rows,
                                  double step, const std::function<double(double, double)>& height) {
  GDALAllRegister();
  GDALDatasetUniquePtr ds(GetGDALDriverManager()->GetDriverByName("GTiff")->Create(path.c_str(), cols, rows,
                                                                                   1, GDT_Float64, nullptr));
  ASSERT_TRUE(ds) << path;
  double gt[6] = {west - 0.5 * step, step, 0.0, north + 0.5 * step, 0.0, -step};
  ds->SetGeoTransform(gt);
  OGRSpatialReference srs;
  srs.importFromEPSG(4326);
  ds->SetSpatialRef(&srs);
  std::vector<double> z(std::size_t(cols) * std::size_t(rows));
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) z[std::size_t(r) * cols + c] = height(west + c * step, north - r * step);
  GDALRasterBand* band = ds->GetRasterBand(1);
  band->SetNoDataValue(std::numeric_limits<double>::quiet_NaN());
  ASSERT_EQ(band->RasterIO(GF_Write, 0, 0, cols, rows, z.data(), cols, rows, GDT_Float64, 0, 0), CE_None)
      << path;
}

}  // namespace terralod::test
