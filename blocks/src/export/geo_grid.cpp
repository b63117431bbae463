// Longitude/latitude grids with ellipsoidal heights (see geo_grid.hpp): GDAL warps what is not
// geographic WGS 84 already, PROJ gives the geoid undulation of every sample.
#include "terralod/blocks/geo_grid.hpp"

#include <gdal_priv.h>
#include <ogr_spatialref.h>
#include <proj.h>
#include <proj_experimental.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <numbers>
#include <optional>
#include <tuple>
#include <utility>

#include "../frame_scale.hpp"
#include "../gdal_support.hpp"
#include "../gdal_warp.hpp"
#include "terralod/pm/geodesy.hpp"
#include "terralod/pm/parallel.hpp"

namespace terralod::blocks {
namespace {

/// A PROJ context and the operation (lon, lat, H in the datum) -> (lon, lat, ellipsoidal h), for
/// one thread.
class GeoidOperation {
 public:
  GeoidOperation(const std::string& vertical, const std::string& what) : ctx_(proj_context_create()) {
    PJ_CONTEXT* ctx = ctx_.get();
    proj_log_level(ctx, PJ_LOG_NONE);  // failures are reported below, naming the file
    const std::string src = "EPSG:4326+" + (vertical.rfind("EPSG:", 0) == 0 ? vertical.substr(5) : vertical);
    PJ* from = proj_create(ctx, vertical.rfind("EPSG:", 0) == 0 ? src.c_str() : vertical.c_str());
    if (from != nullptr && proj_get_type(from) == PJ_TYPE_VERTICAL_CRS) {  // a bare vertical CRS
      PJ* horizontal = proj_create(ctx, "EPSG:4326");
      PJ* compound = proj_create_compound_crs(ctx, "source", horizontal, from);
      proj_destroy(horizontal);
      proj_destroy(from);
      from = compound;
    }
    PJ* to = proj_create(ctx, "EPSG:4979");
    if (from == nullptr || to == nullptr) {
      proj_destroy(from), proj_destroy(to);
      fail(what, "PROJ does not know the vertical datum '" + vertical + "'");
    }
    PJ_OPERATION_FACTORY_CONTEXT* f = proj_create_operation_factory_context(ctx, nullptr);
    proj_operation_factory_context_set_grid_availability_use(
        ctx, f, PROJ_GRID_AVAILABILITY_DISCARD_OPERATION_IF_MISSING_GRID);
    proj_operation_factory_context_set_spatial_criterion(ctx, f, PROJ_SPATIAL_CRITERION_PARTIAL_INTERSECTION);
    PJ_OBJ_LIST* ops = proj_create_operations(ctx, from, to, f);
    proj_operation_factory_context_destroy(f);
    proj_destroy(from), proj_destroy(to);
    const int n = ops != nullptr ? proj_list_get_count(ops) : 0;
    for (int i = 0; i < n && !op_; ++i) {
      PJ* op = proj_list_get(ctx, ops, i);
      if (op != nullptr && !proj_coordoperation_has_ballpark_transformation(ctx, op)) {
        op_.reset(proj_normalize_for_visualization(ctx, op));  // lon, lat order
      }
      proj_destroy(op);
    }
    proj_list_destroy(ops);
    if (!op_)
      fail(what, "PROJ has no geoid transformation from vertical datum '" + vertical +
                     "' to the WGS 84 ellipsoid (is its grid installed? Debian's proj-data has EGM96's "
                     "egm96_15.gtx; others come from https://cdn.proj.org)");
  }
  GeoidOperation(const GeoidOperation&) = delete;
  GeoidOperation& operator=(const GeoidOperation&) = delete;

  /// N at each (lon[i], lat[i]) into n[i].
  void undulations(const double* lon, const double* lat, double* n, std::size_t count,
                   const std::string& what) {
    std::vector<double> x(lon, lon + count), y(lat, lat + count);
    std::fill(n, n + count, 0.0);
    proj_trans_generic(op_.get(), PJ_FWD, x.data(), sizeof(double), count, y.data(), sizeof(double), count, n,
                       sizeof(double), count, nullptr, 0, 0);
    for (std::size_t i = 0; i < count; ++i)
      if (!std::isfinite(n[i]) || n[i] == HUGE_VAL)
        fail(what, "PROJ gave no geoid height at longitude " + std::to_string(lon[i]) + ", latitude " +
                       std::to_string(lat[i]));
  }

 private:
  [[noreturn]] static void fail(const std::string& what, const std::string& problem) {
    throw GeoError(what + ": " + problem);
  }
  // Owned, so that a constructor that throws (an unknown datum, a missing grid) releases the
  // context and its proj.db connection too; op_ is destroyed first.
  struct ContextDeleter {
    void operator()(PJ_CONTEXT* c) const { proj_context_destroy(c); }
  };
  struct PjDeleter {
    void operator()(PJ* p) const { proj_destroy(p); }
  };
  std::unique_ptr<PJ_CONTEXT, ContextDeleter> ctx_;
  std::unique_ptr<PJ, PjDeleter> op_;
};

/// work(op, p) for every piece p < pieces, on one thread per 2^16 of the `samples` (at most one a
/// core), each with its own GeoidOperation (PJ objects are not shared between threads, and one
/// takes milliseconds to make) taking every threads-th piece.
template <class Work>
void with_geoid_operations(const std::string& vertical, const std::string& what, std::size_t samples,
                           std::size_t pieces, Work&& work) {
  const int threads =
      int(std::clamp<std::size_t>(std::min(samples >> 16, pieces), 1, std::size_t(pm::thread_count(0))));
  pm::parallel_for(std::size_t(threads), threads, [&](std::size_t k) {
    GeoidOperation op(vertical, what);
    for (std::size_t p = k; p < pieces; p += std::size_t(threads)) work(op, p);
  });
}

using detail::register_gdal;

bool is_wgs84_geographic(const std::string& wkt) {
  OGRSpatialReference srs, wgs84;
  if (srs.importFromWkt(wkt.c_str()) != OGRERR_NONE || !srs.IsGeographic()) return false;
  if (detail::has_ellipsoidal_height_axis(srs)) srs.DemoteTo2D(nullptr);  // EPSG:4979: its heights aside
  wgs84.SetWellKnownGeogCS("WGS84");
  return srs.IsSameGeogCS(&wgs84) != 0;
}

/// A pole inside the terrain's footprint (its samples' cells): +1 the North Pole, -1 the South
/// Pole, and where it lies in the grid (fractional column and row).
struct PoleAt {
  int pole = 0;
  double col = 0, row = 0;
};
std::optional<PoleAt> pole_inside(const pm::GridTransform& t, int width, int height,
                                  const detail::GeographicOf& geo) {
  const detail::Affine grid{t};
  for (const int s : {1, -1}) {
    double x = 0.0, y = 90.0 * s;
    if (!geo.to_crs->Transform(1, &x, &y) || !std::isfinite(x) || !std::isfinite(y)) continue;
    const auto [c, r] = grid.inverse(x, y);
    if (c >= -0.5 && c <= width - 0.5 && r >= -0.5 && r <= height - 0.5) return PoleAt{s, c, r};
  }
  return std::nullopt;
}

/// read(col0, row0, cols, rows, out): the terrain's samples of that window into out, row by row,
/// NaN at holes (detail::WarpSource::read).
using WindowReader = std::function<void(int col0, int row0, int cols, int rows, double* out)>;

/// A longitude/latitude grid to warp to: its size and geotransform, and the degrees of its first
/// column and row, exactly.
struct GridLayout {
  detail::WarpGrid grid;              ///< size and geotransform
  double west = -180.0, north = 0.0;  ///< degrees, exactly: the first column's and row's
};

/// Ground distance between points (c0, r0) and (c1, r1) of the source's grid, on its ellipsoid;
/// 0 where the CRS cannot place them.
double ground_distance(const pm::GridTransform& t, const detail::GeographicOf& geo, double c0, double r0,
                       double c1, double r1) {
  auto [x0, y0] = t.to_world(c0, r0);
  auto [x1, y1] = t.to_world(c1, r1);
  if (!geo.to_geog->Transform(1, &x0, &y0) || !geo.to_geog->Transform(1, &x1, &y1)) return 0.0;
  const pm::Ecef a = pm::ecef_from_geodetic({x0, y0, 0.0}, geo.a, geo.e2),
                 b = pm::ecef_from_geodetic({x1, y1, 0.0}, geo.a, geo.e2);
  const double d = std::hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
  return std::isfinite(d) ? d : 0.0;
}

/// The ellipsoid's radii of curvature at latitude lat (degrees): prime vertical N, meridian M.
std::array<double, 2> radii(const detail::GeographicOf& geo, double lat) {
  const double sin_lat = std::sin(lat * std::numbers::pi / 180.0), w = 1.0 - geo.e2 * sin_lat * sin_lat;
  return {geo.a / std::sqrt(w), geo.a * (1.0 - geo.e2) / (w * std::sqrt(w))};
}

/// The east-west and north-south spacings (ground metres) of a grid aligned with the parallels
/// and meridians that is no coarser than the source's grid at its point (c, r): with the
/// source's column and row steps as vectors (east, north), its band of frequencies, spanned by
/// the reciprocal vectors, reaches |a*_east| + |b*_east| east-west; so, for steps at right angles
/// along the axes, the steps themselves, and finer where they are turned (a grid of square
/// cells turned 3 degrees, as UTM's are 2 degrees off its central meridian at 60 degrees:
/// 0.95 x its step). nullopt where the CRS cannot place the points.
std::optional<std::array<double, 2>> spacing_needed(const pm::GridTransform& t,
                                                    const detail::GeographicOf& geo, double c, double r) {
  double lon[4], lat[4];
  const double dc[4] = {-0.5, 0.5, 0.0, 0.0}, dr[4] = {0.0, 0.0, -0.5, 0.5};
  for (int k = 0; k < 4; ++k) {
    std::tie(lon[k], lat[k]) = t.to_world(c + dc[k], r + dr[k]);
    if (!geo.to_geog->Transform(1, &lon[k], &lat[k]) || !std::isfinite(lon[k]) || !std::isfinite(lat[k]))
      return std::nullopt;
  }
  const double mid = 0.25 * (lat[0] + lat[1] + lat[2] + lat[3]);
  const auto [n, m] = radii(geo, mid);
  const double per_lon = n * std::cos(mid * std::numbers::pi / 180.0) * std::numbers::pi / 180.0,
               per_lat = m * std::numbers::pi / 180.0;
  const double ce = std::remainder(lon[1] - lon[0], 360.0) * per_lon, cn = (lat[1] - lat[0]) * per_lat;
  const double re = std::remainder(lon[3] - lon[2], 360.0) * per_lon, rn = (lat[3] - lat[2]) * per_lat;
  const double det = std::abs(ce * rn - re * cn);
  if (!(det > 0.0) || !std::isfinite(det)) return std::nullopt;
  return std::array<double, 2>{det / (std::abs(rn) + std::abs(cn)), det / (std::abs(re) + std::abs(ce))};
}

/// at(c, r) for every point (c + offset, r + offset), c and r integers, on the edge of the box
/// from (offset, offset) to (width - 1 - offset, height - 1 - offset): with offset -0.5, every
/// cell corner on the edge of a width x height grid's footprint; with 0, its edge samples.
template <class At>
void for_each_edge_point(int width, int height, double offset, At&& at) {
  const int n = width - 1 - int(2 * offset), m = height - 1 - int(2 * offset);
  for (int c = 0; c <= n; ++c) at(c + offset, offset), at(c + offset, m + offset);
  for (int r = 1; r < m; ++r) at(offset, r + offset), at(n + offset, r + offset);
}

/// Degrees of latitude a ground distance spans (on the equator's radius: a little less than on
/// a meridian, so that rows so far apart are no farther apart on the ground).
double degrees_of(double metres, const detail::GeographicOf& geo) {
  return metres / (geo.a * std::numbers::pi / 180.0);
}

void check_samples(std::size_t cols, std::size_t rows, const std::string& what) {
  if (double(cols) * double(rows) > 4e9)
    throw GeoError(what + ": its longitude/latitude grid would hold " + std::to_string(cols) + " x " +
                   std::to_string(rows) + " samples; crop the DEM");
}

/// The longitude/latitude grid for a terrain around a pole (pole: +1 north, -1 south), for which
/// GDAL suggests none (it failed with "Attempt to create 363x0 dataset"): every longitude, from
/// the pole to the footprint's latitude farthest from it. Rows are the source's ground spacing at
/// the pole apart, and so are columns at that farthest latitude; nearer the pole a column spans
/// less (cos(latitude)), so the grid is nowhere coarser than the source and holds about twice the
/// samples of the cap it covers, whatever its size. (A grid laid out with GDAL's resolution near
/// the pole, a column degrees wide and a row a second, missed the source by hundreds of metres.)
/// Columns 0 and width - 1 are both the antimeridian (GeoGrid::wraps); the pole is the last row
/// (south) or the first.
GridLayout polar_layout(const pm::GridTransform& t, int width, int height, const detail::GeographicOf& geo,
                        const PoleAt& at, const std::string& what) {
  const int pole = at.pole;
  const double pc = at.col, pr = at.row;
  const double spacing = std::min(ground_distance(t, geo, pc - 0.5, pr, pc + 0.5, pr),
                                  ground_distance(t, geo, pc, pr - 0.5, pc, pr + 0.5));
  // The footprint's edge, its latitude farthest from the pole.
  double from_pole = 0.0;  // degrees of latitude
  for_each_edge_point(width, height, -0.5, [&](double c, double r) {
    auto [x, y] = t.to_world(c, r);
    if (geo.to_geog->Transform(1, &x, &y) && std::isfinite(y))
      from_pole = std::max(from_pole, 90.0 - pole * y);
  });
  // Degrees on multiples of 2^-20 (10 cm): rows * dlat is then exact, and the pole's row lies at
  // exactly +-90 degrees, on the tiles' edge.
  const double dlat = std::floor(degrees_of(spacing, geo) * 0x1p20) * 0x1p-20;
  if (!(dlat > 0.0) || !std::isfinite(dlat))
    throw GeoError(what +
                   ": cannot find the terrain's sample spacing at the pole to lay out its "
                   "longitude/latitude grid");
  const double edge_cos = std::max(std::sin(from_pole * std::numbers::pi / 180.0), 1e-9);
  const std::size_t cols = std::size_t(std::ceil(360.0 * edge_cos / dlat - 1e-9)) + 1,
                    rows = std::size_t(std::ceil(from_pole / dlat - 1e-9)) + 1;
  check_samples(cols, rows, what);
  GridLayout l;
  l.grid.width = int(cols), l.grid.height = int(rows);
  // The last column at exactly 180 degrees: (cols - 1) * dlon == 360 in doubles, for 360 / (cols - 1)
  // or one of its neighbours.
  double dlon = 360.0 / double(cols - 1);
  for (const double d : {dlon, std::nextafter(dlon, 0.0), std::nextafter(dlon, 360.0)})
    if (double(cols - 1) * d == 360.0) dlon = d;
  l.north = pole > 0 ? 90.0 : -90.0 + double(rows - 1) * dlat;
  l.grid.gt = {l.west - 0.5 * dlon, dlon, 0.0, l.north + 0.5 * dlat, 0.0, -dlat};
  return l;
}

/// The longitude/latitude grid for any other terrain in a CRS other than geographic WGS 84: the
/// box of the footprint's edge samples in WGS 84 (longitudes continuous around `centre` when it is
/// given); rows as far apart as the source's north-south resolution and columns its east-west
/// one (spacing_needed, the finest at the corners, edge midpoints and centre) where a degree is
/// longest: rows on the meridian's radius farthest from the equator, columns on the parallel
/// nearest it. A geographic source keeps its own steps. So the grid is nowhere coarser than the
/// source. (GDAL suggests cells square in degrees, as many along the diagonal as the source has:
/// on a 90 m UTM DEM rows 106 m apart at 44 degrees north and 187 m at 70, with its bilinear
/// kernel widened to match.) nullopt when an edge sample cannot be transformed (GDAL then lays
/// the grid out).
std::optional<GridLayout> ground_layout(const pm::GridTransform& t, int width, int height,
                                        const detail::GeographicOf& geo, const std::string& crs_wkt,
                                        std::optional<double> centre, const std::string& what) {
  OGRSpatialReference source, wgs84;
  source.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  wgs84.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  wgs84.SetWellKnownGeogCS("WGS84");
  if (source.SetFromUserInput(crs_wkt.c_str()) != OGRERR_NONE) return std::nullopt;
  const detail::Transform to_wgs84(OGRCreateCoordinateTransformation(&source, &wgs84));
  if (!to_wgs84) return std::nullopt;
  double west = HUGE_VAL, east = -HUGE_VAL, south = HUGE_VAL, north = -HUGE_VAL;
  bool placed = true;
  for_each_edge_point(width, height, 0.0, [&](double c, double r) {
    auto [x, y] = t.to_world(c, r);
    if (!to_wgs84->Transform(1, &x, &y) || !std::isfinite(x) || !std::isfinite(y)) {
      placed = false;
      return;
    }
    if (centre) x = *centre + std::remainder(x - *centre, 360.0);
    west = std::min(west, x), east = std::max(east, x), south = std::min(south, y),
    north = std::max(north, y);
  });
  if (!placed || !(west < east) || !(south < north)) return std::nullopt;
  double dlat = 0.0, dlon = 0.0;
  if (source.IsGeographic() && t.xr == 0.0 && t.yc == 0.0) {
    dlat = std::abs(t.yr), dlon = std::abs(t.xc);
  } else {
    double east_west = HUGE_VAL, north_south = HUGE_VAL;
    for (const double fc : {0.0, 0.5, 1.0})
      for (const double fr : {0.0, 0.5, 1.0})
        if (const std::optional<std::array<double, 2>> d =
                spacing_needed(t, geo, fc * (width - 1), fr * (height - 1)))
          east_west = std::min(east_west, (*d)[0]), north_south = std::min(north_south, (*d)[1]);
    // Rows on the meridian's radius of curvature where it is largest (farthest from the
    // equator), columns on the parallel nearest the equator.
    const double nearest_equator =
        south <= 0.0 && north >= 0.0 ? 0.0 : std::min(std::abs(south), std::abs(north));
    const double farthest = std::max(std::abs(south), std::abs(north));
    dlat = north_south / (radii(geo, farthest)[1] * std::numbers::pi / 180.0);
    dlon = east_west /
           (radii(geo, nearest_equator)[0] *
            std::max(std::cos(nearest_equator * std::numbers::pi / 180.0), 1e-9) * std::numbers::pi / 180.0);
  }
  if (!(dlat > 0.0) || !(dlon > 0.0) || !std::isfinite(dlat) || !std::isfinite(dlon)) return std::nullopt;
  const std::size_t cols = std::size_t(std::ceil((east - west) / dlon - 1e-9)) + 1,
                    rows = std::size_t(std::ceil((north - south) / dlat - 1e-9)) + 1;
  check_samples(cols, rows, what);
  GridLayout l;
  l.grid.width = int(cols), l.grid.height = int(rows);
  l.west = west, l.north = north;
  l.grid.gt = {west - 0.5 * dlon, dlon, 0.0, north + 0.5 * dlat, 0.0, -dlat};
  return l;
}

/// One point, one height: where columns 0 and width - 1 are one meridian (GeoGrid::period), the
/// last takes the first's samples, and a row at a pole takes its first sample everywhere, so that the tiles
/// on either side of the antimeridian, and those that meet at a pole, share their edge vertices exactly (a
/// warp and PROJ's geoid give the copies of one point the same height only up to rounding).
void join_meridian_and_poles(GeoGrid& g) {
  const std::size_t w = std::size_t(g.width);
  const auto copy = [&](std::size_t from, std::size_t to) {
    g.heights[to] = g.heights[from];
    if (!g.mask.empty()) g.mask[to] = g.mask[from];
  };
  if (g.period() == g.width - 1)
    for (std::size_t r = 0; r < std::size_t(g.height); ++r) copy(r * w, r * w + w - 1);
  for (const int r : {0, g.height - 1})
    if (std::abs(g.lat(r)) == 90.0)
      for (std::size_t c = 1; c < w; ++c) copy(std::size_t(r) * w, std::size_t(r) * w + c);
}

/// The terrain of width x height samples in the CRS and transform of `frame` (whose samples, if
/// any, are not read: they come from `read`, see detail::WarpSource) warped to EPSG:4326 (bilinear, on
/// polar_layout's grid around a pole, ground_layout's elsewhere, GDAL's where that finds none), voids
/// and outside as holes. Only the warped grid is held whole.
GeoGrid warp_to_lonlat(const pm::Heightfield& frame, int width, int height, const WindowReader& read,
                       const std::string& what) {
  // The source as GDAL sees it: the terrain and a ring of samples around it, each continuing
  // the terrain's edge linearly (twice the edge sample less the one inside it; the edge sample
  // where that one is a hole): a ring of NaN would not do, since GDAL writes no output sample
  // whose nearest source sample is NaN. The output then reaches a sample and a half beyond the
  // terrain's outermost samples, and every point of the terrain lies between output samples
  // that hold its surface. Without the ring, output samples beyond the footprint's cell edge were
  // holes, read as the background, and the outermost DEM samples stood in a cliff: up to 315 m
  // off on a UTM crop of N44W072; now 10 m, as inside (a ring level with the edge: 14 m).
  const pm::GridTransform& inner = *frame.crs_transform;
  const pm::GridTransform t{inner.x0 - inner.xc - inner.xr, inner.xc, inner.xr,
                            inner.y0 - inner.yc - inner.yr, inner.yc, inner.yr};
  const int inner_width = width, inner_height = height;
  width += 2, height += 2;
  detail::WarpSource src;
  src.width = width;
  src.height = height;
  src.gt = {t.x0 - 0.5 * t.xc - 0.5 * t.xr, t.xc, t.xr, t.y0 - 0.5 * t.yc - 0.5 * t.yr, t.yc, t.yr};
  std::vector<double> window;
  src.read = [&](int col0, int row0, int cols, int rows, double* out) {
    // The terrain's samples under the window (its rows and columns -1 .. n are the ring), and one
    // more inward for the ring's slope.
    const auto span = [](int first, int count, int n) {
      return std::pair{std::max(0, std::clamp(first - 1, 0, n - 1) - 1),
                       std::min(n - 1, std::clamp(first + count - 2, 0, n - 1) + 1)};
    };
    const auto [c0, c1] = span(col0, cols, inner_width);
    const auto [r0, r1] = span(row0, rows, inner_height);
    const std::size_t w = std::size_t(c1 - c0 + 1);
    window.resize(w * std::size_t(r1 - r0 + 1));
    read(c0, r0, c1 - c0 + 1, r1 - r0 + 1, window.data());
    const auto continued = [](double edge, double in) { return in == in ? 2.0 * edge - in : edge; };
    const auto in_row = [&](int r, int c) {  // r a row of the terrain, c in -1 .. inner_width
      const auto z = [&](int col) { return window[std::size_t(r - r0) * w + std::size_t(col - c0)]; };
      if (c >= 0 && c < inner_width) return z(c);
      const int edge = c < 0 ? 0 : inner_width - 1;
      return inner_width < 2 ? z(edge) : continued(z(edge), z(c < 0 ? 1 : inner_width - 2));
    };
    for (int r = row0 - 1; r < row0 - 1 + rows; ++r)
      for (int c = col0 - 1; c < col0 - 1 + cols; ++c) {
        if (r >= 0 && r < inner_height) {
          *out++ = in_row(r, c);
          continue;
        }
        const int edge = r < 0 ? 0 : inner_height - 1;
        *out++ = inner_height < 2 ? in_row(edge, c)
                                  : continued(in_row(edge, c), in_row(r < 0 ? 1 : inner_height - 2, c));
      }
  };
  register_gdal();
  OGRSpatialReference wgs84;
  wgs84.SetWellKnownGeogCS("WGS84");
  char* dst_wkt = nullptr;
  wgs84.exportToWkt(&dst_wkt);
  std::string dst = dst_wkt != nullptr ? dst_wkt : "";
  CPLFree(dst_wkt);
  // Far from Greenwich, longitudes run continuously around the terrain's centre (PROJ's
  // lon_wrap): a terrain across the antimeridian would otherwise land on both edges of
  // [-180, 180], and its grid would span the whole Earth with the terrain cut in two.
  std::optional<GridLayout> layout;
  if (const std::optional<detail::GeographicOf> geo = detail::geographic_of(frame.crs_wkt)) {
    if (const std::optional<PoleAt> pole = pole_inside(t, width, height, *geo)) {
      layout = polar_layout(t, width, height, *geo, *pole, what);  // every longitude meets there
    } else {
      std::optional<double> centre;
      auto [x, y] = t.to_world(0.5 * (width - 1), 0.5 * (height - 1));
      if (geo->to_geog->Transform(1, &x, &y) && std::abs(x) > 90.0) {  // x: the centre's longitude
        const std::string wrap = std::to_string(x);
        dst = "+proj=longlat +datum=WGS84 +lon_wrap=" + wrap + " +no_defs";
        centre = std::stod(wrap);  // as PROJ reads it
      }
      layout = ground_layout(t, width, height, *geo, frame.crs_wkt, centre, what);
    }
  }
  std::string error;
  detail::WarpGrid w = detail::warp_grid(src, frame.crs_wkt, dst, error, layout ? &layout->grid : nullptr);
  if (!error.empty())
    throw GeoError(what + ": GDAL could not warp the terrain from its CRS to longitude/latitude: " + error);
  GeoGrid g;
  g.width = w.width;
  g.height = w.height;
  g.dlon = w.gt[1];
  g.dlat = -w.gt[5];
  g.west = layout ? layout->west : w.gt[0] + 0.5 * w.gt[1];
  g.north = layout ? layout->north : w.gt[3] + 0.5 * w.gt[5];
  g.heights = std::move(w.z);
  g.mask.assign(g.heights.size(), 1);
  bool any = false;
  for (std::size_t i = 0; i < g.heights.size(); ++i) {
    if (!std::isfinite(g.heights[i])) {
      g.mask[i] = 0;
      g.heights[i] = 0.0f;
    } else {
      any = true;
    }
  }
  if (!any) throw GeoError(what + ": no sample is left after warping to longitude/latitude");
  g.horizontal = "warped from its CRS to EPSG:4326 by GDAL (bilinear), " + std::to_string(g.width) + " x " +
                 std::to_string(g.height) + " samples";
  return g;
}

void require_crs(const pm::Heightfield& frame, const std::string& what) {
  if (frame.crs_wkt.empty() || !frame.crs_transform)
    throw GeoError(what +
                   ": the terrain has no coordinate reference system, so it cannot be placed on the "
                   "Earth; build it from a georeferenced DEM (an SRTM .hgt, a GeoTIFF with a CRS, an "
                   ".asc with a .prj; gdal_translate -a_srs EPSG:<code> adds one)");
}

/// The grid of a terrain on a north-up WGS 84 longitude/latitude grid (on_lonlat_grid): its own
/// samples as floats, 0 and masked at holes, read in windows of `window` rows and 16 `window`
/// columns, so that nothing but the grid grows with the terrain.
GeoGrid own_samples(const pm::Heightfield& frame, int width, int height, int window,
                    const WindowReader& read) {
  const pm::GridTransform& t = *frame.crs_transform;
  GeoGrid g;
  g.width = width;
  g.height = height;
  g.west = t.x0;
  g.north = t.y0;
  g.dlon = t.xc;
  g.dlat = -t.yr;
  const std::size_t w = std::size_t(width);
  g.heights.resize(w * std::size_t(height));
  std::vector<double> buf;
  for (int r0 = 0; r0 < height; r0 += window)
    for (int c0 = 0; c0 < width; c0 += 16 * window) {
      const SampleRect rect{c0, r0, std::min(width - 1, c0 + 16 * window - 1),
                            std::min(height - 1, r0 + window - 1)};
      buf.resize(rect.samples());
      read(rect.col0, rect.row0, rect.width(), rect.height(), buf.data());
      const double* in = buf.data();
      for (int r = rect.row0; r <= rect.row1; ++r)
        for (std::size_t i = std::size_t(r) * w + std::size_t(rect.col0), end = i + std::size_t(rect.width());
             i < end; ++i, ++in) {
          if (*in == *in) {
            g.heights[i] = float(*in);
            continue;
          }
          if (g.mask.empty()) g.mask.assign(g.heights.size(), 1);
          g.mask[i] = 0;
          g.heights[i] = 0.0f;
        }
    }
  g.horizontal = "the source's own samples (geographic WGS 84)";
  return g;
}

/// Whether the grid of `frame` is north-up in geographic WGS 84: then its samples are the grid's.
bool on_lonlat_grid(const pm::Heightfield& frame) {
  const pm::GridTransform& t = *frame.crs_transform;
  return is_wgs84_geographic(frame.crs_wkt) && t.xr == 0.0 && t.yc == 0.0 && t.xc > 0.0 && t.yr < 0.0;
}

/// Adds the geoid undulation of the vertical CRS v to every valid sample of g.
void convert_to_ellipsoid(GeoGrid& g, const std::string& v, const std::string& what) {
  // N varies smoothly (PROJ interpolates a 15' grid for EGM96), but every sample gets its own,
  // in bands of whole rows of about 2^16 samples: the coordinates and undulations (24 bytes a
  // sample) are never held for more than a band a thread.
  const int band = std::max(1, (1 << 16) / g.width);
  const int bands = (g.height + band - 1) / band;
  with_geoid_operations(
      v, what, g.heights.size(), std::size_t(bands), [&](GeoidOperation& op, std::size_t b) {
        const int r0 = int(b) * band, r1 = std::min(g.height, r0 + band);
        std::vector<double> lon, lat, n;
        for (int r = r0; r < r1; ++r)
          for (int c = 0; c < g.width; ++c) {
            lon.push_back(std::remainder(g.lon(c), 360.0));  // past 180 across the antimeridian
            lat.push_back(g.lat(r));
          }
        n.assign(lon.size(), 0.0);
        op.undulations(lon.data(), lat.data(), n.data(), n.size(), what);
        const std::size_t at = std::size_t(r0) * std::size_t(g.width);
        for (std::size_t i = 0; i < n.size(); ++i)
          if (g.mask.empty() || g.mask[at + i]) g.heights[at + i] = float(double(g.heights[at + i]) + n[i]);
      });
  g.heights_converted = true;
}

/// g's heights from the datum `requested` (the caller's, else the one its source states; "" when
/// neither names one) to the WGS 84 ellipsoid (the header's contract).
GeoGrid with_ellipsoidal_heights(GeoGrid g, const std::string& requested, const std::string& what) {
  const std::string v = detail::vertical_crs(requested);
  g.vertical_datum = v.empty()          ? "WGS 84 ellipsoid"
                     : v == "EPSG:5773" ? "EGM96"
                     : v == "EPSG:3855" ? "EGM2008"
                                        : v;
  if (requested.empty()) g.vertical_datum += " (assumed: the source states no vertical datum)";
  if (!v.empty()) convert_to_ellipsoid(g, v, what);
  // After the geoid, which gives the copies of one point the same height only up to rounding.
  join_meridian_and_poles(g);
  return g;
}

}  // namespace

std::vector<double> geoid_undulations(const std::string& vertical_datum, const std::vector<double>& lon,
                                      const std::vector<double>& lat, const std::string& what) {
  std::vector<double> n(lon.size(), 0.0);
  const std::string v = detail::vertical_crs(vertical_datum);
  if (v.empty() || lon.empty()) return n;
  constexpr std::size_t kPiece = 1 << 16;
  with_geoid_operations(v, what, lon.size(), (lon.size() + kPiece - 1) / kPiece,
                        [&](GeoidOperation& op, std::size_t p) {
                          const std::size_t a = p * kPiece, b = std::min(lon.size(), a + kPiece);
                          op.undulations(lon.data() + a, lat.data() + a, n.data() + a, b - a, what);
                        });
  return n;
}

GeoGrid make_geo_grid(pm::Heightfield hf, const std::string& vertical_datum, const std::string& what) {
  require_crs(hf, what);
  const std::string requested = vertical_datum.empty() ? hf.vertical_datum : vertical_datum;
  const WindowReader read = [&](int col0, int row0, int cols, int rows, double* out) {
    for (int r = 0; r < rows; ++r)
      for (int c = 0; c < cols; ++c)
        *out++ = hf.valid(col0 + c, row0 + r) ? hf.at(col0 + c, row0 + r)
                                              : std::numeric_limits<double>::quiet_NaN();
  };
  GeoGrid g = on_lonlat_grid(hf) ? own_samples(hf, hf.width(), hf.height(), 256, read)
                                 : warp_to_lonlat(hf, hf.width(), hf.height(), read, what);
  std::vector<double>().swap(hf.samples());
  return with_ellipsoidal_heights(std::move(g), requested, what);
}

GeoGrid make_geo_grid(DatabaseTerrain& terrain, const std::string& vertical_datum, const std::string& what) {
  const pm::Heightfield& frame = terrain.frame();
  require_crs(frame, what);
  const WindowReader read = [&](int col0, int row0, int cols, int rows, double* out) {
    terrain.read({col0, row0, col0 + cols - 1, row0 + rows - 1}, out);  // straight into the caller's buffer
  };
  // Own samples: a row of blocks at a time, 16 blocks a read (decoded in parallel).
  GeoGrid g = on_lonlat_grid(frame) ? own_samples(frame, terrain.width(), terrain.height(),
                                                  terrain.layout().block_size - 1, read)
                                    : warp_to_lonlat(frame, terrain.width(), terrain.height(), read, what);
  return with_ellipsoidal_heights(std::move(g),
                                  vertical_datum.empty() ? frame.vertical_datum : vertical_datum, what);
}

}  // namespace terralod::blocks
