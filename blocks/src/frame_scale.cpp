// detail::scale_error and its coordinate helpers (frame_scale.hpp), and frame_scale_error
// (dem_grid.hpp), which measures a grid held in memory through it.
#include "frame_scale.hpp"

#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <numbers>
#include <tuple>

#include "gdal_support.hpp"
#include "terralod/blocks/dem_grid.hpp"
#include "terralod/blocks/ground_scale.hpp"
#include "terralod/pm/geodesy.hpp"

namespace terralod::blocks {

namespace detail {

namespace {
constexpr double kDeg = std::numbers::pi / 180.0;
}  // namespace

void TransformDeleter::operator()(OGRCoordinateTransformation* t) const {
  OGRCoordinateTransformation::DestroyCT(t);
}

bool transform(OGRCoordinateTransformation& ct, std::vector<double>& x, std::vector<double>& y) {
  std::vector<int> ok(x.size(), 0);
  if (x.empty()) return true;
  if (!ct.Transform(int(x.size()), x.data(), y.data(), nullptr, ok.data())) return false;
  return std::all_of(ok.begin(), ok.end(), [](int v) { return v != 0; });
}

std::optional<GeographicOf> geographic_of(const std::string& crs_wkt) {
  register_gdal();
  OGRSpatialReference crs;
  if (crs.importFromWkt(crs_wkt.c_str()) != OGRERR_NONE) return std::nullopt;
  crs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRSpatialReference> geog(crs.CloneGeogCS());
  if (!geog) return std::nullopt;
  geog->SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  GeographicOf g;
  g.to_geog.reset(OGRCreateCoordinateTransformation(&crs, geog.get()));
  g.to_crs.reset(OGRCreateCoordinateTransformation(geog.get(), &crs));
  if (!g.to_geog || !g.to_crs) return std::nullopt;
  const double b = crs.GetSemiMinor();
  g.a = crs.GetSemiMajor(), g.e2 = 1.0 - (b * b) / (g.a * g.a);
  if (!(g.a > 0) || !std::isfinite(g.e2)) return std::nullopt;
  return g;
}

std::optional<std::pair<double, double>> scale_range(
    const std::vector<double>& lon, const std::vector<double>& lat, double a, double e2,
    const std::function<bool(std::vector<double>&, std::vector<double>&)>& to_frame) {
  // Four neighbours at +-step degrees, through to_frame. Points within 0.1 degree of a pole are
  // left out: the east metres per degree vanish there, and a neighbour beyond the pole (a pixel
  // edge of a DEM that reaches 90 degrees lies half a pixel past it) is no point of any frame.
  constexpr double step = 1e-3;
  std::vector<std::size_t> at;
  std::vector<double> x, y;
  for (std::size_t i = 0; i < lon.size(); ++i) {
    if (!(std::abs(lat[i]) <= 89.9)) continue;
    at.push_back(i);
    x.insert(x.end(), {lon[i] + step, lon[i] - step, lon[i], lon[i]});
    y.insert(y.end(), {lat[i], lat[i], lat[i] + step, lat[i] - step});
  }
  if (at.empty()) return std::pair{1.0, 1.0};  // no point away from the poles
  if (!to_frame(x, y)) return std::nullopt;
  double lo = 1e300, hi = -1e300;
  for (std::size_t j = 0; j < at.size(); ++j) {
    const std::size_t i = at[j];
    const double phi = lat[i] * kDeg, s = std::sin(phi);
    const double n = a / std::sqrt(1.0 - e2 * s * s), m = n * (1.0 - e2) / (1.0 - e2 * s * s);
    const double east = n * std::cos(phi) * kDeg * 2.0 * step, north = m * kDeg * 2.0 * step;
    const std::size_t k = 4 * j;
    const double ex = (x[k] - x[k + 1]) / east, ey = (y[k] - y[k + 1]) / east;
    const double nx = (x[k + 2] - x[k + 3]) / north, ny = (y[k + 2] - y[k + 3]) / north;
    const double t = ex * ex + ey * ey + nx * nx + ny * ny, d = std::abs(ex * ny - nx * ey);
    const double root = std::sqrt(std::max(0.0, t * t - 4.0 * d * d));
    const double s1 = std::sqrt(0.5 * (t + root)), s2 = std::sqrt(std::max(0.0, 0.5 * (t - root)));
    lo = std::min(lo, s2), hi = std::max(hi, s1);
  }
  return std::pair{lo, hi};
}

std::optional<double> scale_error(const std::string& crs_wkt,
                                  const std::optional<pm::GridTransform>& crs_transform,
                                  const pm::GridTransform& world, int w, int h,
                                  const std::function<bool(int, int)>& valid,
                                  const std::function<std::pair<int, int>(int)>& row_ends) {
  if (crs_wkt.empty() || !crs_transform) return std::nullopt;
  QuietGdal quiet;
  std::optional<GeographicOf> geo = geographic_of(crs_wkt);
  if (!geo) return std::nullopt;
  Transform& to_geog = geo->to_geog;
  Transform& to_crs = geo->to_crs;
  const double a = geo->a, e2 = geo->e2;

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

  const Affine samples{*crs_transform};
  const std::optional<std::pair<double, double>> range =
      scale_range(lon, lat, a, e2, [&](std::vector<double>& x, std::vector<double>& y) {
        if (!transform(*to_crs, x, y)) return false;
        for (std::size_t k = 0; k < x.size(); ++k) {
          const auto [c, r] = samples.inverse(x[k], y[k]);
          std::tie(x[k], y[k]) = world.to_world(c, r);
        }
        return true;
      });
  if (!range) return std::nullopt;
  // |s - 1| over the points is largest at the smallest or the largest scale.
  return std::max(std::abs(range->first - 1.0), std::abs(range->second - 1.0));
}

std::optional<GroundFrame> GroundFrame::open(const std::string& crs_wkt,
                                             const pm::GridTransform& crs_transform,
                                             const pm::GridTransform& world) {
  if (crs_wkt.empty()) return std::nullopt;
  QuietGdal quiet;
  std::optional<GeographicOf> geo = geographic_of(crs_wkt);
  if (!geo) return std::nullopt;
  GroundFrame g;
  g.to_geog_ = std::move(geo->to_geog);
  g.crs_ = Affine{crs_transform}, g.world_ = Affine{world};
  g.a_ = geo->a, g.e2_ = geo->e2;
  return g;
}

std::optional<pm::GroundScale> GroundFrame::at(double x, double y) const {
  constexpr double h = 10.0;  // metres of world offset
  std::vector<double> px{x + h, x - h, x, x}, py{y, y, y + h, y - h};
  for (std::size_t k = 0; k < px.size(); ++k) {
    const auto [c, r] = world_.inverse(px[k], py[k]);
    std::tie(px[k], py[k]) = crs_.t.to_world(c, r);
  }
  QuietGdal quiet;
  if (!transform(*to_geog_, px, py)) return std::nullopt;
  // Earth-centred coordinates of the points on the CRS's ellipsoid.
  std::array<pm::Ecef, 4> p;
  for (std::size_t k = 0; k < 4; ++k) p[k] = pm::ecef_from_geodetic({px[k], py[k], 0.0}, a_, e2_);
  double dx[3], dy[3];
  for (int i = 0; i < 3; ++i) dx[i] = (p[0][i] - p[1][i]) / (2 * h), dy[i] = (p[2][i] - p[3][i]) / (2 * h);
  // J^T J and its square root: sqrt(M) = (M + sqrt(det M) I) / sqrt(tr M + 2 sqrt(det M)).
  const double mxx = dx[0] * dx[0] + dx[1] * dx[1] + dx[2] * dx[2];
  const double mxy = dx[0] * dy[0] + dx[1] * dy[1] + dx[2] * dy[2];
  const double myy = dy[0] * dy[0] + dy[1] * dy[1] + dy[2] * dy[2];
  const double sd = std::sqrt(std::max(0.0, mxx * myy - mxy * mxy)), t = std::sqrt(mxx + myy + 2.0 * sd);
  if (!(t > 0) || !std::isfinite(t)) return std::nullopt;
  const pm::GroundScale g{(mxx + sd) / t, mxy / t, (myy + sd) / t};
  if (!(g.min_scale() >= 0.5 && g.max_scale() <= 2.0)) return std::nullopt;
  return g;
}

}  // namespace detail

GroundScaleMap::GroundScaleMap() = default;
GroundScaleMap::GroundScaleMap(GroundScaleMap&&) noexcept = default;
GroundScaleMap& GroundScaleMap::operator=(GroundScaleMap&&) noexcept = default;
GroundScaleMap::~GroundScaleMap() = default;

GroundScaleMap::GroundScaleMap(const std::string& crs_wkt,
                               const std::optional<pm::GridTransform>& crs_transform,
                               const pm::GridTransform& world, const pm::Box& box)
    : box_(box) {
  if (!crs_transform) return;
  if (auto g = detail::GroundFrame::open(crs_wkt, *crs_transform, world))
    frame_ = std::make_unique<detail::GroundFrame>(std::move(*g));
}

GroundScaleMap GroundScaleMap::of(const pm::Heightfield& hf) {
  pm::Box box{{1e300, 1e300, 0.0}, {-1e300, -1e300, 0.0}};
  for (const auto& [c, r] :
       {std::pair{0, 0}, {hf.width() - 1, 0}, {0, hf.height() - 1}, {hf.width() - 1, hf.height() - 1}}) {
    const auto [x, y] = hf.transform.to_world(c, r);
    box.lo.x = std::min(box.lo.x, x), box.lo.y = std::min(box.lo.y, y);
    box.hi.x = std::max(box.hi.x, x), box.hi.y = std::max(box.hi.y, y);
  }
  return GroundScaleMap(hf.crs_wkt, hf.crs_transform, hf.transform, box);
}

pm::GroundScale GroundScaleMap::at(double x, double y) const {
  if (!frame_) return {};
  const std::optional<pm::GroundScale> g =
      frame_->at(std::clamp(x, box_.lo.x, box_.hi.x), std::clamp(y, box_.lo.y, box_.hi.y));
  return g ? *g : pm::GroundScale{};
}

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

}  // namespace terralod::blocks
