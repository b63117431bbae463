// The "auto" frame of a geographic DEM (DemOptions::crs "auto", dem_frame.hpp): which projection,
// centred where, and the factor k0 that balances its scale error.
//
// "auto" for a geographic DEM: the azimuthal equidistant projection (Snyder, Map Projections - A
// Working Manual, USGS 1987, ch. 25) centred on the DEM. On the sphere its radial scale is 1 and
// its tangential scale c / sin(c), c = angular distance from the centre (Snyder eq. 25-2 with
// k' = c / sin c). Multiplying the world coordinates by k0 = 2 / (1 + s_max), s_max = c_max /
// sin(c_max) over the DEM's corners, puts every scale in [k0, k0 s_max] = [1 - d, 1 + d] with
// d = (s_max - 1) / (s_max + 1) ~ c_max^2 / 12: 0.081 % for an 8 x 8 degree DEM on the equator
// (c_max = 5.66 degrees), under 0.1 % up to c_max ~ 6.3 degrees (9 x 9 degrees on the equator).
// Beyond that, auto_frame measures more candidates over the part of the footprint that may hold
// data and takes the truest: a conformal projection's scale grows with the square of the distance
// from its line of true scale (k ~ 1 + d^2 / 2: the central meridian of a transverse Mercator, the
// standard parallel of a conic, the equator of a Mercator, the central great circle of an oblique
// Mercator), so balanced it is within ~ d_max^2 / 4 whatever the strip's length, against
// c_max^2 / 12 of the azimuthal frame, whose c_max grows with the length. Finding the covered part
// asks the native source about 4,096 cells (GDAL's data coverage: about 0.4 ms each on a VRT of
// 3,240 tiles), only when the azimuthal frame is over 0.1 %.
#include "dem_auto_frame.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include "frame_scale.hpp"
#include "gdal_support.hpp"
#include "terralod/blocks/dem_reader.hpp"

namespace terralod::blocks::detail {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

/// The great circle that best fits points on the unit sphere (lon, lat degrees): its centre
/// (lon, lat, the points' mean direction moved onto it) and its azimuth there (degrees east of
/// north), from the pole of the circle, the eigenvector of the smallest eigenvalue of the points'
/// second-moment matrix (Jacobi rotations on the 3 x 3 matrix). nullopt for fewer than 2 points
/// or when the fit is not defined (all points at one place).
struct GreatCircle {
  double lon, lat, azimuth;
};
std::optional<GreatCircle> fit_great_circle(const std::vector<double>& lon, const std::vector<double>& lat) {
  if (lon.size() < 2) return std::nullopt;
  double m[3][3] = {}, mean[3] = {};
  for (std::size_t i = 0; i < lon.size(); ++i) {
    const double v[3] = {std::cos(lat[i] * kDeg) * std::cos(lon[i] * kDeg),
                         std::cos(lat[i] * kDeg) * std::sin(lon[i] * kDeg), std::sin(lat[i] * kDeg)};
    for (int a = 0; a < 3; ++a) {
      mean[a] += v[a];
      for (int b = 0; b < 3; ++b) m[a][b] += v[a] * v[b];
    }
  }
  double e[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};  // columns: eigenvectors
  for (int sweep = 0; sweep < 50; ++sweep) {
    const double off = std::abs(m[0][1]) + std::abs(m[0][2]) + std::abs(m[1][2]);
    if (off <= 1e-15 * (std::abs(m[0][0]) + std::abs(m[1][1]) + std::abs(m[2][2]))) break;
    for (int p = 0; p < 2; ++p)
      for (int q = p + 1; q < 3; ++q) {
        if (m[p][q] == 0.0) continue;
        const double theta = 0.5 * std::atan2(2.0 * m[p][q], m[q][q] - m[p][p]);
        const double c = std::cos(theta), sn = std::sin(theta);
        for (int k = 0; k < 3; ++k) {  // m = J^T m J
          const double mkp = m[k][p], mkq = m[k][q];
          m[k][p] = c * mkp - sn * mkq, m[k][q] = sn * mkp + c * mkq;
        }
        for (int k = 0; k < 3; ++k) {
          const double mpk = m[p][k], mqk = m[q][k];
          m[p][k] = c * mpk - sn * mqk, m[q][k] = sn * mpk + c * mqk;
        }
        for (int k = 0; k < 3; ++k) {
          const double ekp = e[k][p], ekq = e[k][q];
          e[k][p] = c * ekp - sn * ekq, e[k][q] = sn * ekp + c * ekq;
        }
      }
  }
  int smallest = 0;
  for (int k = 1; k < 3; ++k)
    if (m[k][k] < m[smallest][smallest]) smallest = k;
  const double n[3] = {e[0][smallest], e[1][smallest], e[2][smallest]};
  const double along = mean[0] * n[0] + mean[1] * n[1] + mean[2] * n[2];
  double c[3] = {mean[0] - along * n[0], mean[1] - along * n[1], mean[2] - along * n[2]};
  const double len = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
  if (!(len > 1e-9)) return std::nullopt;
  for (double& v : c) v /= len;
  const double lat_c = std::asin(std::clamp(c[2], -1.0, 1.0)), lon_c = std::atan2(c[1], c[0]);
  const double t[3] = {n[1] * c[2] - n[2] * c[1], n[2] * c[0] - n[0] * c[2], n[0] * c[1] - n[1] * c[0]};
  const double east = -std::sin(lon_c) * t[0] + std::cos(lon_c) * t[1];
  const double north = -std::sin(lat_c) * std::cos(lon_c) * t[0] - std::sin(lat_c) * std::sin(lon_c) * t[1] +
                       std::cos(lat_c) * t[2];
  double azimuth = std::atan2(east, north) / kDeg;
  if (azimuth > 90.0) azimuth -= 180.0;  // the same circle, heading the other way
  if (azimuth <= -90.0) azimuth += 180.0;
  return GreatCircle{lon_c / kDeg, lat_c / kDeg, azimuth};
}

/// The cells of a division of a w x h grid into at most 64 x 64 that may hold data: those
/// native.may_have_data, and the empty ones that reading fills (each 4-connected group of empty
/// cells whose bounding box holds at most native.filled_void_cells() samples, the void fill's own
/// limit). Empty when every cell may hold data, or none does: nothing is known then.
std::vector<SampleRect> covered_cells(const DemSource& native, int w, int h) {
  const int nc = std::min(64, w), nr = std::min(64, h);
  const auto cell = [&](std::size_t k) {
    const std::int64_t i = std::int64_t(k % std::size_t(nc)), j = std::int64_t(k / std::size_t(nc));
    return SampleRect{int(w * i / nc), int(h * j / nr), int(w * (i + 1) / nc) - 1, int(h * (j + 1) / nr) - 1};
  };
  std::vector<std::uint8_t> has(std::size_t(nc) * std::size_t(nr));
  for (std::size_t k = 0; k < has.size(); ++k) has[k] = native.may_have_data(cell(k)) ? 1 : 0;
  if (const std::size_t fills = native.filled_void_cells(); fills > 0) {
    std::vector<std::uint8_t> seen(has.size());
    std::vector<std::size_t> group, stack;
    for (std::size_t start = 0; start < has.size(); ++start) {
      if (has[start] || seen[start]) continue;
      group.clear(), stack.assign(1, start), seen[start] = 1;
      SampleRect box = cell(start);
      while (!stack.empty()) {
        const std::size_t k = stack.back();
        stack.pop_back();
        group.push_back(k);
        const SampleRect r = cell(k);
        box = {std::min(box.col0, r.col0), std::min(box.row0, r.row0), std::max(box.col1, r.col1),
               std::max(box.row1, r.row1)};
        const int i = int(k % std::size_t(nc)), j = int(k / std::size_t(nc));
        for (const auto& [a, b] : {std::pair{i + 1, j}, {i - 1, j}, {i, j + 1}, {i, j - 1}}) {
          if (a < 0 || b < 0 || a >= nc || b >= nr) continue;
          const std::size_t m = std::size_t(b) * std::size_t(nc) + std::size_t(a);
          if (!has[m] && !seen[m]) seen[m] = 1, stack.push_back(m);
        }
      }
      if (box.samples() <= fills)
        for (const std::size_t k : group) has[k] = 1;
    }
  }
  std::vector<SampleRect> covered;
  for (std::size_t k = 0; k < has.size(); ++k)
    if (has[k]) covered.push_back(cell(k));
  if (covered.size() == has.size()) covered.clear();
  return covered;
}

}  // namespace

/// Chooses the "auto" frame of a geographic DEM whose (col, row) -> (lon, lat) is `st` over a
/// w x h grid, read through `native`. The azimuthal equidistant projection centred on the grid
/// whenever its balanced scale error over the grid's rectangle is within 0.1 % (every extent up to
/// about 9 x 9 degrees; its k0 is Snyder's spherical formula, so frames and databases of earlier
/// versions stay the same). Otherwise the candidate whose measured scale range is narrowest over
/// the covered part of the footprint (the cells of a 64 x 64 division that native.may_have_data,
/// or whose group of empty cells the void fill would fill (native.filled_void_cells):
/// a mosaic of tiles along a coast is judged by its tiles, not by the ocean around them; every
/// cell when nothing is known), balanced by k0 = 2 / (min + max): that azimuthal frame; an
/// azimuthal one centred on the covered cells; a transverse Mercator on their central meridian (a
/// north-south strip: its scale grows with the distance from that meridian only, so a strip
/// about 7 degrees wide stays within 0.1 % however long); a Lambert conformal conic with one
/// standard parallel at their central latitude (an east-west strip away from the equator); a
/// Mercator (an east-west strip along the equator); and an oblique Mercator along the great
/// circle that best fits them (a strip in any direction). A later candidate replaces an earlier
/// one only when it is truer by 2 %, so near-ties go to the simpler projection. An extent wide in
/// both directions (a continent) is beyond every projection: the best one is taken and the frame
/// says so.
AutoFrame auto_frame(const std::string& path, const OGRSpatialReference& source, const pm::GridTransform& st,
                     int w, int h, const DemSource& native) {
  const auto [lon_c, lat_c] = st.to_world(0.5 * (w - 1), 0.5 * (h - 1));
  double c_max = 0.0;
  for (const auto& [c, r] : {std::pair{-0.5, -0.5}, {w - 0.5, -0.5}, {-0.5, h - 0.5}, {w - 0.5, h - 0.5}}) {
    const auto [lon, lat] = st.to_world(c, r);
    const double cos_c = std::sin(lat_c * kDeg) * std::sin(lat * kDeg) +
                         std::cos(lat_c * kDeg) * std::cos(lat * kDeg) * std::cos((lon - lon_c) * kDeg);
    c_max = std::max(c_max, std::acos(std::clamp(cos_c, -1.0, 1.0)));
  }
  const double s_max = c_max > 0.0 ? c_max / std::sin(c_max) : 1.0;

  // Where the candidates are measured. The whole footprint: its pixel edges, a 17 x 17 lattice
  // over it and 65 points along each side.
  std::vector<double> lon, lat;
  const auto add = [&](double c, double r) {
    const auto [x, y] = st.to_world(c, r);
    lon.push_back(x), lat.push_back(y);
  };
  for (int i = 0; i <= 16; ++i)
    for (int j = 0; j <= 16; ++j) add(-0.5 + w * i / 16.0, -0.5 + h * j / 16.0);
  for (int k = 0; k <= 64; ++k) {
    const double fc = -0.5 + w * k / 64.0, fr = -0.5 + h * k / 64.0;
    add(fc, -0.5), add(fc, h - 0.5), add(-0.5, fr), add(w - 0.5, fr);
  }
  const double a = source.GetSemiMajor(), b = source.GetSemiMinor(), e2 = 1.0 - (b * b) / (a * a);
  const auto deg = [](double v) { return format("%.9g", v); };
  struct Candidate {
    std::string name;
    std::function<OGRErr(OGRSpatialReference&)> set;
    std::string where;
  };
  struct Measured {
    OGRSpatialReference crs;
    double k0 = 1.0, error = 1e300;
  };
  // The candidate's scale error over the points, balanced by `k0` (or, 0, by its own range).
  const auto measure = [&](const Candidate& cand, double k0) -> std::optional<Measured> {
    Measured m;
    m.crs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    if (m.crs.CopyGeogCSFrom(&source) != OGRERR_NONE || cand.set(m.crs) != OGRERR_NONE) return std::nullopt;
    const Transform ct(OGRCreateCoordinateTransformation(&source, &m.crs));
    if (!ct) return std::nullopt;
    const double unit = m.crs.GetLinearUnits(nullptr);
    const auto range =
        detail::scale_range(lon, lat, a, e2, [&](std::vector<double>& x, std::vector<double>& y) {
          if (!transform(*ct, x, y)) return false;
          for (std::size_t k = 0; k < x.size(); ++k) x[k] *= unit, y[k] *= unit;
          return true;
        });
    if (!range || !(range->first > 0.0)) return std::nullopt;  // outside the projection's domain
    m.k0 = k0 > 0.0 ? k0 : 2.0 / (range->first + range->second);
    m.error = std::max(std::abs(m.k0 * range->first - 1.0), std::abs(m.k0 * range->second - 1.0));
    return m;
  };
  const Candidate aeqd{"azimuthal equidistant",
                       [&](OGRSpatialReference& t) { return t.SetAE(lat_c, lon_c, 0.0, 0.0); },
                       "centred at lon " + deg(lon_c) + ", lat " + deg(lat_c)};
  const std::string tail = "; world = k0 * CRS metres, k0 = ";
  const std::optional<Measured> first = measure(aeqd, 2.0 / (1.0 + s_max));
  // Within the promise over the whole rectangle: the frame of earlier versions.
  if (first && first->error <= 0.001)
    return AutoFrame{
        first->crs, first->k0,
        aeqd.name + " (auto) on " + name_of(source) + ", " + aeqd.where + tail + format("%.12g", first->k0),
        first->error};

  // Beyond it: when some cells are known to be empty, the corners and centres of the covered
  // cells instead of the whole footprint.
  const std::vector<SampleRect> covered = covered_cells(native, w, h);
  const bool whole = covered.empty();
  if (!whole) {
    lon.clear(), lat.clear();
    for (const SampleRect& r : covered) {
      add(r.col0 - 0.5, r.row0 - 0.5), add(r.col1 + 0.5, r.row0 - 0.5);
      add(r.col0 - 0.5, r.row1 + 0.5), add(r.col1 + 0.5, r.row1 + 0.5);
      add(0.5 * (r.col0 + r.col1), 0.5 * (r.row0 + r.row1));
    }
  }
  // The measured part's middle: of its longitudes and latitudes, and the great circle along it.
  const auto [lon_lo, lon_hi] = std::minmax_element(lon.begin(), lon.end());
  const auto [lat_lo, lat_hi] = std::minmax_element(lat.begin(), lat.end());
  const double lon_m = 0.5 * (*lon_lo + *lon_hi), lat_m = 0.5 * (*lat_lo + *lat_hi);
  const std::optional<GreatCircle> line = fit_great_circle(lon, lat);
  std::vector<Candidate> candidates = {
      aeqd,
      {"azimuthal equidistant", [&](OGRSpatialReference& t) { return t.SetAE(lat_m, lon_m, 0.0, 0.0); },
       "centred at lon " + deg(lon_m) + ", lat " + deg(lat_m)},
      {"transverse Mercator", [&](OGRSpatialReference& t) { return t.SetTM(lat_m, lon_m, 1.0, 0.0, 0.0); },
       "central meridian lon " + deg(lon_m) + ", origin at lat " + deg(lat_m)},
      {"Lambert conformal conic",
       [&](OGRSpatialReference& t) { return t.SetLCC1SP(lat_m, lon_m, 1.0, 0.0, 0.0); },
       "standard parallel lat " + deg(lat_m) + ", central meridian lon " + deg(lon_m)},
      {"Mercator", [&](OGRSpatialReference& t) { return t.SetMercator(0.0, lon_m, 1.0, 0.0, 0.0); },
       "central meridian lon " + deg(lon_m)},
  };
  if (line)
    candidates.push_back({"oblique Mercator",
                          [&](OGRSpatialReference& t) {
                            return t.SetHOMAC(line->lat, line->lon, line->azimuth, line->azimuth, 1.0, 0.0,
                                              0.0);
                          },
                          "central line through lon " + deg(line->lon) + ", lat " + deg(line->lat) +
                              " at azimuth " + deg(line->azimuth)});

  AutoFrame best;
  double best_error = 1e300, aeqd_error = 1e300;
  for (const Candidate& cand : candidates) {
    const bool is_first = &cand == &candidates.front();
    const std::optional<Measured> m =
        is_first && whole ? first : measure(cand, is_first ? 2.0 / (1.0 + s_max) : 0.0);
    if (!m) continue;
    if (is_first) aeqd_error = m->error;
    if (best_error == 1e300 || m->error < 0.98 * best_error) {
      best_error = m->error;
      best.crs = m->crs;
      best.k0 = m->k0;
      best.error = m->error;
      best.description =
          cand.name + " (auto) on " + name_of(source) + ", " + cand.where + tail + format("%.12g", m->k0);
      if (!is_first)
        best.description += " (chosen for its scale error of +-" + format("%.3f", m->error * 100.0) +
                            " % over " + (whole ? "the footprint" : "the covered part of the footprint") +
                            " against the azimuthal equidistant frame's +-" +
                            format("%.3f", aeqd_error * 100.0) + " %)";
    }
  }
  if (best_error == 1e300)
    throw DemError(path, "GDAL cannot make any of the projections of --crs auto on its datum: " +
                             gdal_message("unknown reason"));
  return best;
}

}  // namespace terralod::blocks::detail
