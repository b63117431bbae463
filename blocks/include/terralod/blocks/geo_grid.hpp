// A terrain's samples on a longitude/latitude grid with WGS 84 ellipsoidal heights: what the
// exporters to the formats of CesiumJS and friends need (they place vertices by longitude,
// latitude and height above the ellipsoid).
//
// Usage:
//   namespace tb = terralod::blocks;
//   pm::Heightfield hf = tb::read_database_terrain(db);          // crs_wkt, crs_transform set
//   tb::GeoGrid g = tb::make_geo_grid(std::move(hf), /*vertical_datum=*/"", "terrain.db");
//   double h = g.z(col, row);                                    // metres above WGS 84
//   double lon = g.lon(col), lat = g.lat(row);                   // degrees
//   tb::DatabaseTerrain terrain(db);                             // or read window by window:
//   tb::GeoGrid g2 = tb::make_geo_grid(terrain, "", "terrain.db");  // the same grid
//
// Contract of make_geo_grid:
//   - hf must carry its CRS (crs_wkt and crs_transform, as read_dem and read_database_terrain
//     give them); otherwise GeoError naming `what` and asking for a georeferenced input.
//   - Horizontal: a north-up grid in a geographic CRS on the WGS 84 datum is used as it is (the
//     samples are the DEM's own). Anything else (a projected CRS, a rotated grid, another datum)
//     is warped to EPSG:4326 through GDAL (bilinear; the same samples however GDAL cuts the warp
//     into chunks), and the warped samples are the grid's samples; voids and the area outside
//     the source become holes. The source is first continued linearly by one sample all around,
//     so that the grid reaches a sample and a half beyond its outermost samples (which then lie
//     between grid samples of their own surface, not at a cliff down to the holes). The grid is
//     laid out here, nowhere coarser than the source: rows as far apart as the source's
//     north-south resolution, columns its east-west one on the footprint's parallel nearest the
//     equator (both from the source's column and row steps at nine points of it; a geographic
//     source on another datum keeps its own steps), over the footprint's box. A terrain that
//     holds a pole (a polar stereographic DEM) gets every longitude, from the pole to the
//     footprint's farthest latitude, rows the source's ground spacing at the pole apart and
//     columns that far apart where they are widest (about twice the samples of the cap it
//     covers). GDAL lays the grid out only where the CRS cannot place the footprint's edge.
//   - One point, one height: where columns 0 and width - 1 are one meridian (period() is
//     width - 1), the last takes the first's samples, and a row at +-90 degrees takes its first
//     sample everywhere, after the geoid, so that tiles meeting there share their vertices.
//   - Vertical: heights are converted from `vertical_datum` to the WGS 84 ellipsoid by adding
//     the geoid undulation N(lon, lat) that PROJ gives for every sample:
//       "ellipsoid" (or "wgs84")  the heights are ellipsoidal already: nothing is added;
//       "egm96"                   EPSG:5773 (EGM96 height; grid egm96_15 from Debian's proj-data);
//       "egm2008"                 EPSG:3855 (EGM2008 height; needs PROJ's egm08_25 grid);
//       any other text            a PROJ vertical CRS ("EPSG:5703", ...);
//       "" (empty)                the datum the source states (hf.vertical_datum: EGM96 for
//                                 .hgt, the vertical CRS of a compound CRS, the ellipsoid of a 3D
//                                 CRS such as EPSG:4979), and EGM96 when it states none (SRTM,
//                                 GMTED, ASTER and most global DEMs use it).
//     GeoError when PROJ does not know the datum or lacks its grid (PROJ is never allowed to fall
//     back silently to a no-op "ballpark" transformation).
//   - From a DatabaseTerrain: the same grid, bit for bit, as from read_database_terrain's whole
//     grid. A terrain on a longitude/latitude grid is read a row of blocks at a time (its samples
//     are the grid's); one to warp is read window by window as GDAL's warp needs it (chunks of 8
//     MiB, each read straight into GDAL's buffer), so its source is never held whole.
//   - Costs: the grid, 4 bytes per sample (floats) and 1 more where it has holes; from a
//     Heightfield, hf's samples are freed once copied (pass hf with std::move unless it is
//     needed afterwards); a warp writes straight into the grid and reads the source by windows
//     (a Heightfield's in place: it is held anyway); PROJ evaluates N once per sample, in bands
//     of rows of about 2^16 samples.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "terralod/blocks/database_terrain.hpp"
#include "terralod/pm/heightfield.hpp"

namespace terralod::blocks {

/// A georeferencing problem: what() = "<file>: <problem>".
class GeoError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct GeoGrid {
  int width = 0, height = 0;
  double west = 0, north = 0;  ///< degrees: longitude of column 0, latitude of row 0 (north)
  double dlon = 0, dlat = 0;   ///< degrees between columns and between rows (both > 0)
  /// WGS 84 ellipsoidal heights, metres, row-major; floats (4 bytes a sample), which hold any
  /// height on Earth to within 1 mm of the double computed (0.5 mm a rounding, twice where the
  /// geoid is added to a rounded height); 0 at holes.
  std::vector<float> heights;
  std::vector<std::uint8_t> mask;  ///< 1 valid, 0 hole; empty when every sample is valid
  std::string vertical_datum;      ///< what the heights were converted from, as resolved
  bool heights_converted = false;  ///< false: the source's heights were ellipsoidal already
  std::string horizontal;          ///< "the source's own samples" or how they were warped

  double lon(double col) const { return west + col * dlon; }
  double lat(double row) const { return north - row * dlat; }
  double z(int col, int row) const { return double(heights[std::size_t(row) * width + col]); }
  bool valid(int col, int row) const { return mask.empty() || mask[std::size_t(row) * width + col] != 0; }
  /// Columns per turn around the Earth: width - 1 when columns 0 and width - 1 are one meridian
  /// ((width - 1) dlon = 360 degrees, a grid from -180 to 180; make_geo_grid gives them the same
  /// samples), width when column `width` would be column 0 again (width dlon = 360 degrees: the
  /// cell-registered global grids of GEBCO, ETOPO, SRTM15+), 0 when the grid does not go around.
  int period() const {
    if (width > 1 && std::abs(double(width - 1) * dlon - 360.0) <= 1e-9) return width - 1;
    return std::abs(double(width) * dlon - 360.0) <= 1e-9 ? width : 0;
  }
  bool wraps() const { return period() > 0; }
};

GeoGrid make_geo_grid(pm::Heightfield hf, const std::string& vertical_datum, const std::string& what);
/// The same grid from a database's terrain, read window by window where it is warped.
GeoGrid make_geo_grid(DatabaseTerrain& terrain, const std::string& vertical_datum, const std::string& what);

/// The geoid undulation N (metres: ellipsoidal height = height in `vertical_datum` + N) at
/// (lon, lat) in degrees, by the same PROJ operation make_geo_grid uses. GeoError as above.
std::vector<double> geoid_undulations(const std::string& vertical_datum, const std::vector<double>& lon,
                                      const std::vector<double>& lat, const std::string& what);

}  // namespace terralod::blocks
