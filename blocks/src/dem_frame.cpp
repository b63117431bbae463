// The world frames of read_dem beyond the native one (DemOptions::crs): a projected CRS chosen per
// terrain ("auto") or named by the user, reached by one GDAL warp, and the worst scale error of
// any georeferenced frame, measured against the CRS's ellipsoid.
//
// "auto" for a geographic DEM: the azimuthal equidistant projection (Snyder, Map Projections - A
// Working Manual, USGS 1987, ch. 25) centred on the DEM. On the sphere its radial scale is 1 and
// its tangential scale c / sin(c), c = angular distance from the centre (Snyder eq. 25-2 with
// k' = c / sin c). Multiplying the world coordinates by k0 = 2 / (1 + s_max), s_max = c_max /
// sin(c_max) over the DEM's corners, puts every scale in [k0, k0 s_max] = [1 - d, 1 + d] with
// d = (s_max - 1) / (s_max + 1) ~ c_max^2 / 12: 0.081 % for an 8 x 8 degree DEM on the equator
// (c_max = 5.66 degrees), under 0.1 % up to c_max ~ 6.3 degrees (9 x 9 degrees on the equator).
// The scale error recorded in the frame is measured, not taken from that formula: the singular
// values of the Jacobian of (east, north metres on the ellipsoid) -> world at every lattice sample
// and at both ends of every row of valid samples. Memory: the source and warped grids.
#include "dem_frame.hpp"

#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <numbers>
#include <optional>

#include "gdal_support.hpp"
#include "gdal_warp.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/void_fill.hpp"

namespace terralod::blocks {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;
constexpr double kNan = std::numeric_limits<double>::quiet_NaN();

using detail::gdal_message;
using detail::QuietGdal;
using detail::register_gdal;

struct TransformDeleter {
  void operator()(OGRCoordinateTransformation* t) const { OGRCoordinateTransformation::DestroyCT(t); }
};
using Transform = std::unique_ptr<OGRCoordinateTransformation, TransformDeleter>;

std::string format(const char* fmt, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt, v);
  return buf;
}

std::string wkt_of(const OGRSpatialReference& srs) {
  char* text = nullptr;
  std::string out;
  if (srs.exportToWkt(&text) == OGRERR_NONE && text != nullptr) out = text;
  CPLFree(text);
  return out;
}

std::string name_of(const OGRSpatialReference& srs) {
  const char* name = srs.GetName();
  return name != nullptr ? name : "unnamed CRS";
}

/// (col, row) -> (x, y) of an affine map and back.
struct Affine {
  pm::GridTransform t;
  std::pair<double, double> inverse(double x, double y) const {
    const double det = t.xc * t.yr - t.xr * t.yc, dx = x - t.x0, dy = y - t.y0;
    return {(t.yr * dx - t.xr * dy) / det, (t.xc * dy - t.yc * dx) / det};
  }
};

/// Transforms the points in place; false when any fails.
bool transform(OGRCoordinateTransformation& ct, std::vector<double>& x, std::vector<double>& y) {
  std::vector<int> ok(x.size(), 0);
  if (x.empty()) return true;
  if (!ct.Transform(int(x.size()), x.data(), y.data(), nullptr, ok.data())) return false;
  return std::all_of(ok.begin(), ok.end(), [](int v) { return v != 0; });
}

}  // namespace

namespace detail {

std::optional<double> scale_error(const std::string& crs_wkt,
                                  const std::optional<pm::GridTransform>& crs_transform,
                                  const pm::GridTransform& world, int w, int h,
                                  const std::function<bool(int, int)>& valid,
                                  const std::function<std::pair<int, int>(int)>& row_ends) {
  if (crs_wkt.empty() || !crs_transform) return std::nullopt;
  register_gdal();
  QuietGdal quiet;
  OGRSpatialReference crs;
  if (crs.importFromWkt(crs_wkt.c_str()) != OGRERR_NONE) return std::nullopt;
  crs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRSpatialReference> geog(crs.CloneGeogCS());
  if (!geog) return std::nullopt;
  geog->SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  Transform to_geog(OGRCreateCoordinateTransformation(&crs, geog.get()));
  Transform to_crs(OGRCreateCoordinateTransformation(geog.get(), &crs));
  if (!to_geog || !to_crs) return std::nullopt;
  const double a = crs.GetSemiMajor(), b = crs.GetSemiMinor(), e2 = 1.0 - (b * b) / (a * a);

  // Where to measure: a 33 x 33 lattice and both ends of every row, valid samples only.
  std::vector<double> cols, rows;
  auto add = [&](int c, int r) {
    if (valid(c, r)) cols.push_back(c), rows.push_back(r);
  };
  for (int i = 0; i <= 32; ++i)
    for (int j = 0; j <= 32; ++j)
      add(int(std::lround((w - 1) * i / 32.0)), int(std::lround((h - 1) * j / 32.0)));
  for (int r = 0; r < h; ++r) {
    const auto [first, last] = row_ends(r);
    if (first < w)
      cols.insert(cols.end(), {double(first), double(last)}), rows.insert(rows.end(), {double(r), double(r)});
  }
  std::vector<double> lon(cols.size()), lat(cols.size());
  for (std::size_t i = 0; i < cols.size(); ++i)
    std::tie(lon[i], lat[i]) = crs_transform->to_world(cols[i], rows[i]);
  if (!transform(*to_geog, lon, lat)) return std::nullopt;

  // Four neighbours at +-step degrees, through the CRS and the samples to the world frame.
  constexpr double step = 1e-3;
  std::vector<double> x, y;
  for (std::size_t i = 0; i < lon.size(); ++i) {
    x.insert(x.end(), {lon[i] + step, lon[i] - step, lon[i], lon[i]});
    y.insert(y.end(), {lat[i], lat[i], lat[i] + step, lat[i] - step});
  }
  if (!transform(*to_crs, x, y)) return std::nullopt;
  const Affine samples{*crs_transform};
  for (std::size_t k = 0; k < x.size(); ++k) {
    const auto [c, r] = samples.inverse(x[k], y[k]);
    std::tie(x[k], y[k]) = world.to_world(c, r);
  }
  double worst = 0.0;
  for (std::size_t i = 0; i < lon.size(); ++i) {
    const double phi = lat[i] * kDeg, s = std::sin(phi);
    if (std::abs(lat[i]) > 89.9) continue;  // the east metres per degree vanish at a pole
    const double n = a / std::sqrt(1.0 - e2 * s * s), m = n * (1.0 - e2) / (1.0 - e2 * s * s);
    const double east = n * std::cos(phi) * kDeg * 2.0 * step, north = m * kDeg * 2.0 * step;
    const std::size_t k = 4 * i;
    const double ex = (x[k] - x[k + 1]) / east, ey = (y[k] - y[k + 1]) / east;
    const double nx = (x[k + 2] - x[k + 3]) / north, ny = (y[k + 2] - y[k + 3]) / north;
    const double t = ex * ex + ey * ey + nx * nx + ny * ny, d = std::abs(ex * ny - nx * ey);
    const double root = std::sqrt(std::max(0.0, t * t - 4.0 * d * d));
    const double s1 = std::sqrt(0.5 * (t + root)), s2 = std::sqrt(std::max(0.0, 0.5 * (t - root)));
    worst = std::max({worst, std::abs(s1 - 1.0), std::abs(s2 - 1.0)});
  }
  return worst;
}

}  // namespace detail

std::optional<double> frame_scale_error(const pm::Heightfield& hf) {
  const int w = hf.width();
  return detail::scale_error(
      hf.crs_wkt, hf.crs_transform, hf.transform, w, hf.height(),
      [&](int c, int r) { return hf.valid(c, r); },
      [&](int r) {
        int first = 0, last = w - 1;
        while (first < w && !hf.valid(first, r)) ++first;
        while (last > first && !hf.valid(last, r)) --last;
        return std::pair{first, last};
      });
}

namespace detail {

std::string scale_error_note(std::optional<double> e, bool automatic) {
  if (!e) return "";
  std::string note = "; scale error within +-" + format("%.3f", *e * 100.0) + " %";
  if (automatic && *e > 0.001) note += " (over 0.1 %: the best of this frame; name a CRS with --crs)";
  return note;
}

namespace {

/// Appends the measured scale error to hf.frame (nothing without a CRS); for "auto", over
/// 0.1 %, says that this is the frame's limit.
pm::Heightfield with_scale_error(pm::Heightfield hf, bool automatic = false) {
  hf.frame += scale_error_note(frame_scale_error(hf), automatic);
  return hf;
}

/// Whether hf.crs_wkt names a CRS (read into `source`) with a transform to it.
bool read_crs(const std::string& crs_wkt, bool has_crs_transform, OGRSpatialReference& source) {
  return !crs_wkt.empty() && has_crs_transform && source.importFromWkt(crs_wkt.c_str()) == OGRERR_NONE &&
         !source.IsEmpty();
}

}  // namespace

bool frame_warps(const std::string& crs_wkt, bool has_crs_transform, const std::string& crs) {
  if (crs == "native") return false;
  if (crs != "auto") return true;
  register_gdal();
  QuietGdal quiet;
  OGRSpatialReference source;
  return read_crs(crs_wkt, has_crs_transform, source) && source.IsGeographic();
}

pm::Heightfield apply_frame(const std::string& path, pm::Heightfield hf, const std::string& crs) {
  if (!frame_warps(hf.crs_wkt, hf.crs_transform.has_value(), crs)) return with_scale_error(std::move(hf));
  const bool automatic = crs == "auto";
  register_gdal();
  QuietGdal quiet;
  OGRSpatialReference source;
  const bool has_crs = read_crs(hf.crs_wkt, hf.crs_transform.has_value(), source);
  if (!has_crs)
    throw DemError(path, "has no CRS, so it cannot be warped to the CRS '" + crs +
                             "' asked for (--crs, DemOptions::crs); use --crs native or auto");
  source.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  const pm::GridTransform& st = *hf.crs_transform;
  const int w = hf.width(), h = hf.height();

  // The target CRS and, for "auto", the scale k0 that balances its scale error.
  OGRSpatialReference target;
  target.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  double k0 = 1.0;
  std::string description;
  if (automatic) {
    const auto [lon_c, lat_c] = st.to_world(0.5 * (w - 1), 0.5 * (h - 1));
    double c_max = 0.0;
    for (const auto& [c, r] : {std::pair{-0.5, -0.5}, {w - 0.5, -0.5}, {-0.5, h - 0.5}, {w - 0.5, h - 0.5}}) {
      const auto [lon, lat] = st.to_world(c, r);
      const double cos_c = std::sin(lat_c * kDeg) * std::sin(lat * kDeg) +
                           std::cos(lat_c * kDeg) * std::cos(lat * kDeg) * std::cos((lon - lon_c) * kDeg);
      c_max = std::max(c_max, std::acos(std::clamp(cos_c, -1.0, 1.0)));
    }
    const double s_max = c_max > 0.0 ? c_max / std::sin(c_max) : 1.0;
    k0 = 2.0 / (1.0 + s_max);
    if (target.CopyGeogCSFrom(&source) != OGRERR_NONE || target.SetAE(lat_c, lon_c, 0.0, 0.0) != OGRERR_NONE)
      throw DemError(path, "GDAL cannot make an azimuthal equidistant CRS on its datum: " +
                               gdal_message("unknown reason"));
    description = "azimuthal equidistant (auto) on " + name_of(source) + ", centred at lon " +
                  format("%.9g", lon_c) + ", lat " + format("%.9g", lat_c) +
                  "; world = k0 * CRS metres, k0 = " + format("%.12g", k0);
  } else {
    if (target.SetFromUserInput(crs.c_str()) != OGRERR_NONE || target.IsEmpty())
      throw DemError(path, "the CRS '" + crs +
                               "' asked for (--crs, DemOptions::crs) is not one GDAL understands: " +
                               gdal_message("unknown CRS"));
    if (!target.IsProjected())
      throw DemError(path,
                     "the CRS '" + crs +
                         "' asked for (--crs, DemOptions::crs) is not a projected CRS; "
                         "the world frame needs metres (name a projected CRS such as EPSG:32619, or 'auto')");
    description = "CRS '" + name_of(target) + "' (--crs " + crs + "); world = CRS coordinates in metres";
  }
  const double unit = target.GetLinearUnits(nullptr);
  Transform to_target(OGRCreateCoordinateTransformation(&source, &target));
  if (!to_target)
    throw DemError(path, "no transformation from its CRS '" + name_of(source) + "' to '" + name_of(target) +
                             "': " + gdal_message("PROJ found none"));

  // The footprint (pixel edges, every sample along each side) and the spacing at the centre.
  std::vector<double> x, y;
  auto add = [&](double c, double r) {
    const auto [px, py] = st.to_world(c, r);
    x.push_back(px), y.push_back(py);
  };
  add(0.5 * (w - 1), 0.5 * (h - 1));
  add(0.5 * (w - 1) + 1.0, 0.5 * (h - 1));
  add(0.5 * (w - 1), 0.5 * (h - 1) + 1.0);
  for (int c = 0; c <= w; ++c) add(c - 0.5, -0.5), add(c - 0.5, h - 0.5);
  for (int r = 0; r <= h; ++r) add(-0.5, r - 0.5), add(w - 0.5, r - 0.5);
  if (!transform(*to_target, x, y))
    throw DemError(path, "part of it cannot be transformed to '" + name_of(target) + "' (" +
                             gdal_message("outside the CRS's domain?") + ")");
  // The source's ground spacing at its centre, east-west and north-south apart: the warped grid
  // keeps about the source's number of samples (square cells of the smaller one would add 41 % at
  // 44 degrees N). Cells need not be square: every transform downstream is affine.
  const double sx = std::hypot(x[1] - x[0], y[1] - y[0]), sy = std::hypot(x[2] - x[0], y[2] - y[0]);
  const auto [xmin, xmax] = std::minmax_element(x.begin() + 3, x.end());
  const auto [ymin, ymax] = std::minmax_element(y.begin() + 3, y.end());
  const double cols = std::ceil((*xmax - *xmin) / sx), rows = std::ceil((*ymax - *ymin) / sy);
  if (!(sx > 0.0) || !(sy > 0.0) || !std::isfinite(cols) || !std::isfinite(rows) ||
      cols * rows > double(1 << 30))
    throw DemError(path, "its footprint in '" + name_of(target) + "' is degenerate or over 2^30 samples");

  WarpGrid src;
  src.width = w;
  src.height = h;
  src.gt = {st.x0 - 0.5 * st.xc - 0.5 * st.xr, st.xc, st.xr, st.y0 - 0.5 * st.yc - 0.5 * st.yr, st.yc, st.yr};
  src.z = hf.samples();
  for (std::size_t i = 0; i < src.z.size(); ++i)
    if (!hf.valid(i)) src.z[i] = kNan;
  WarpGrid grid;
  grid.width = std::max(2, int(cols));
  grid.height = std::max(2, int(rows));
  const double cx = 0.5 * (*xmin + *xmax), cy = 0.5 * (*ymin + *ymax);
  grid.gt = {cx - 0.5 * grid.width * sx, sx, 0.0, cy + 0.5 * grid.height * sy, 0.0, -sy};
  std::string error;
  WarpGrid out = warp_grid(src, hf.crs_wkt, wkt_of(target), &grid, error);
  if (!error.empty()) throw DemError(path, "GDAL cannot warp it to '" + name_of(target) + "': " + error);

  pm::Heightfield r(out.width, out.height);
  std::vector<std::uint8_t> mask(out.z.size(), 1);
  std::size_t holes = 0;
  for (std::size_t i = 0; i < out.z.size(); ++i)
    if (!std::isfinite(out.z[i])) mask[i] = 0, ++holes;
  if (holes == out.z.size())
    throw DemError(path, "no sample is left after warping it to '" + name_of(target) + "'");
  // The holes stay holes (mask 0), but hold the heights of a harmonic fill (0 where it is capped)
  // so that the coarse surfaces and stand-ins through a hole sample pass near the terrain.
  if (holes > 0) fill_voids(out.z, out.width, out.height);
  for (double& z : out.z)
    if (!std::isfinite(z)) z = 0.0;
  r.samples() = std::move(out.z);
  if (holes > 0) r.set_mask(std::move(mask));
  const double x0 = out.gt[0] + 0.5 * out.gt[1], y0 = out.gt[3] + 0.5 * out.gt[5];
  r.crs_transform = pm::GridTransform::north_up(x0, y0, out.gt[1], -out.gt[5]);
  const double k = k0 * unit;
  r.transform = pm::GridTransform::north_up(k * x0, k * y0, k * out.gt[1], -k * out.gt[5]);
  r.crs_wkt = wkt_of(target);
  r.voids = hf.voids;
  r.vertical_datum = hf.vertical_datum;
  r.source = hf.source;
  r.frame = description + " (unit factor " + format("%.12g", unit) + "); warped by GDAL (bilinear) from " +
            name_of(source) + ", " + format("%.6g", sx * unit * k0) + " x " + format("%.6g", sy * unit * k0) +
            " m cells, " + std::to_string(holes) + " cells outside the source are holes";
  return with_scale_error(std::move(r), automatic);
}

}  // namespace detail

}  // namespace terralod::blocks
