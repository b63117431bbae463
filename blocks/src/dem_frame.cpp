// The world frames of read_dem beyond the native one (DemOptions::crs): a projected CRS chosen per
// terrain ("auto") or named by the user, reached by a warp that reads window by window
// (WarpedSource), and the worst scale error of any georeferenced frame, measured against the
// CRS's ellipsoid.
//
// "auto" for a geographic DEM: the projection dem_auto_frame.cpp chooses.
// The scale error recorded in a frame is measured, not taken from a formula: the singular
// values of the Jacobian of (east, north metres on the ellipsoid) -> world at every lattice sample
// and at both ends of every row of valid samples. Memory: a warped window, its native window and
// its positions (16 bytes a sample); apply_frame holds the native grid and the warped one.
#include "dem_frame.hpp"

#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>

#include "dem_auto_frame.hpp"
#include "gdal_support.hpp"
#include "sample_crc.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/void_fill.hpp"

namespace terralod::blocks {

namespace {

using detail::Affine;
using detail::Transform;
using detail::transform;

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();

using detail::auto_frame;
using detail::AutoFrame;
using detail::format;
using detail::gdal_message;
using detail::name_of;
using detail::QuietGdal;
using detail::register_gdal;

std::string wkt_of(const OGRSpatialReference& srs) {
  char* text = nullptr;
  std::string out;
  if (srs.exportToWkt(&text) == OGRERR_NONE && text != nullptr) out = text;
  CPLFree(text);
  return out;
}

}  // namespace

namespace detail {

std::string scale_error_note(std::optional<double> e, bool automatic) {
  if (!e) return "";
  std::string note = "; scale error within +-" + format("%.3f", *e * 100.0) + " %";
  if (automatic && *e > 0.001)
    note +=
        " (over 0.1 %: the best of the projections auto tries; name a CRS with --crs; the runtime's "
        "view corrects it about the camera)";
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

/// Reads the whole grid of `src` through read(), top to bottom, in bands of whole rows of about
/// 2^18 samples: `band(row0, b)` gets each, so that no pass holds the grid (or a warp's
/// positions, 16 bytes a sample) whole.
void for_each_band(const DemSource& src, const std::function<void(int, const pm::Heightfield&)>& band) {
  const DemGrid& g = src.grid();
  const int rows = std::max(1, (1 << 18) / g.width);
  for (int r0 = 0; r0 < g.height; r0 += rows)
    band(r0, src.read({0, r0, g.width - 1, std::min(g.height, r0 + rows) - 1}));
}

/// warped_source's DemSource (dem_frame.hpp). The target grid is the footprint of the native
/// grid's pixels in the target CRS (every pixel edge along its sides), with the native ground
/// spacing at its centre east-west and north-south apart: the grid keeps about the native number
/// of samples (square cells of the smaller spacing would add 41 % at 44 degrees N). Cells need not
/// be square: every transform downstream is affine.
class WarpedSource final : public DemSource {
 public:
  /// `source`: the native grid's CRS (warp_source_crs); `frame`: for crs "auto", the frame
  /// auto_frame chose (warped_source looks at it first).
  WarpedSource(const std::string& path, std::unique_ptr<DemSource> native, const std::string& crs,
               const std::string& height_note, const OGRSpatialReference& source,
               std::optional<AutoFrame> frame);
  pm::Heightfield read(SampleRect window) const override;
  std::uint32_t samples_crc() const override;
  bool in_memory() const override { return native_->in_memory(); }
  VoidFillWork void_fill_work() const override { return native_->void_fill_work(); }

 private:
  /// Exact transformations at every step_-th sample of every step_-th row (see the header).
  int step_ = 1;
  /// How far bilinear positions may be from exact ones, in samples (choose_step measures it): a
  /// height then moves by at most 2e-3 of the largest step between neighbouring samples, a
  /// millimetre or two on SRTM's 1 m steps; GDAL's own approximate transformer allows 0.125.
  /// Exact transformations cost about 2 microseconds each for the ellipsoidal "auto" frame (PROJ's
  /// geodesics), so a step of 16 instead of 2 takes a full read of 10^9 samples from ~500 s to ~8 s.
  static constexpr double kPositionTolerance = 1e-3;
  /// Warped heights are rounded to multiples of 2^-kHeightBits metres (1/64 m: at most 7.8 mm
  /// off, below the resampling's own change on any slope): a block's PM then stores its heights
  /// as integers (pm_io.cpp), not as 8 raw bytes each, which took a warped SRTM mosaic's blocks
  /// from 2.9 to 9.8 bytes per vertex.
  static constexpr int kHeightBits = 6;
  struct Pos {
    double c, r;  ///< position in the native grid (sample units); NaN where the transform failed
  };
  /// The native positions of the samples of `window`, row-major, exact every `step` samples.
  void positions(SampleRect window, int step, std::vector<Pos>& out) const;
  /// The largest step of 16, 8, 4, 2 (else 1: every sample exact) whose bilinear positions are
  /// within kPositionTolerance of the exact ones at the midpoints of cells spread over the grid.
  int choose_step() const;
  /// Interpolates the samples of `piece` (inside `window`, whose positions `pos` holds) into b and
  /// mask (b's samples: `window`), reading the native grid once for the piece, or splitting it
  /// when the native window it needs is much larger than itself (a long row across curved
  /// parallels, say): no value depends on how pieces are cut.
  void interpolate(SampleRect window, SampleRect piece, const std::vector<Pos>& pos, pm::Heightfield& b,
                   std::vector<std::uint8_t>& mask) const;

  std::string path_;
  std::unique_ptr<DemSource> native_;
  int nw_ = 0, nh_ = 0;  ///< native grid size
  Affine native_crs_;    ///< native (col, row) <-> native CRS
  Transform to_native_;  ///< target CRS -> native CRS; cloned for each concurrent reader
  /// A geographic native CRS: the longitude of the native grid's centre. PROJ returns longitudes
  /// in [-180, 180]; a grid that crosses the antimeridian (a DEM of Fiji or the Aleutians from
  /// 179.5 to 180.5) has longitudes beyond, so positions() takes each longitude within 180
  /// degrees of this one (NaN: a projected native CRS).
  double native_lon_ = std::numeric_limits<double>::quiet_NaN();
  mutable std::mutex mutex_;
  mutable std::vector<Transform> pool_;  ///< clones no read is using
};

/// The CRS of a native grid that is to be warped to the frame `crs`; DemError naming `path` when
/// it has none.
OGRSpatialReference warp_source_crs(const std::string& path, const DemGrid& ng, const std::string& crs) {
  OGRSpatialReference source;
  if (!read_crs(ng.crs_wkt, ng.crs_transform.has_value(), source))
    throw DemError(path, "has no CRS, so it cannot be warped to the CRS '" + crs +
                             "' asked for (--crs, DemOptions::crs); use --crs native or auto");
  source.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  return source;
}

/// A native source that "auto" keeps as it is (beyond kFlatFrameLimit): its samples and grid,
/// with a frame description that says why and gives the native frame's measured scale error.
class NativeKept final : public DemSource {
 public:
  NativeKept(std::unique_ptr<DemSource> native, const AutoFrame& best, const std::string& height_note)
      : native_(std::move(native)) {
    grid_ = native_->grid();
    grid_.scale_error = scale_error_by_reads(grid_, [this](SampleRect r) { return native_->read(r); });
    grid_.frame += " (--crs auto keeps the DEM's own grid: no flat projection holds its extent within +-" +
                   format("%.0f", kFlatFrameLimit * 100.0) + " %; the truest, " +
                   best.description.substr(0, best.description.find(" (auto)")) + ", is within +-" +
                   format("%.3f", best.error * 100.0) +
                   " %; the runtime's view corrects distances about the camera)" +
                   scale_error_note(grid_.scale_error, false) + height_note;
  }
  pm::Heightfield read(SampleRect window) const override {
    pm::Heightfield b = native_->read(window);
    b.frame = grid_.frame;
    return b;
  }
  pm::Heightfield read_counting_voids(SampleRect window, std::size_t& file_voids) const override {
    pm::Heightfield b = native_->read_counting_voids(window, file_voids);
    b.frame = grid_.frame;
    return b;
  }
  std::uint32_t samples_crc() const override { return native_->samples_crc(); }
  bool in_memory() const override { return native_->in_memory(); }
  bool may_have_data(SampleRect window) const override { return native_->may_have_data(window); }
  std::size_t filled_void_cells() const override { return native_->filled_void_cells(); }
  VoidFillWork void_fill_work() const override { return native_->void_fill_work(); }

 private:
  std::unique_ptr<DemSource> native_;
};

WarpedSource::WarpedSource(const std::string& path, std::unique_ptr<DemSource> native, const std::string& crs,
                           const std::string& height_note, const OGRSpatialReference& source,
                           std::optional<AutoFrame> frame)
    : path_(path), native_(std::move(native)) {
  const DemGrid& ng = native_->grid();
  const bool automatic = crs == "auto";
  QuietGdal quiet;
  const pm::GridTransform& st = *ng.crs_transform;
  nw_ = ng.width, nh_ = ng.height;
  native_crs_ = Affine{st};
  const int w = nw_, h = nh_;

  // The target CRS and, for "auto", the scale k0 that balances its scale error.
  OGRSpatialReference target;
  target.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  double k0 = 1.0;
  std::string description;
  if (automatic) {
    target = frame.value().crs;
    target.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);  // a copy may not keep it
    k0 = frame->k0;
    description = std::move(frame->description);
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
  to_native_.reset(OGRCreateCoordinateTransformation(&target, &source));
  if (!to_target || !to_native_)
    throw DemError(path, "no transformation from its CRS '" + name_of(source) + "' to '" + name_of(target) +
                             "': " + gdal_message("PROJ found none"));

  // The footprint (pixel edges, every sample along each side) and the spacing at the centre. A
  // geographic DEM whose outer samples lie on a pole has its pixel edges half a pixel beyond it,
  // which no projection maps: they are taken at the pole.
  const bool geographic = source.IsGeographic();
  if (geographic) native_lon_ = st.to_world(0.5 * (w - 1), 0.5 * (h - 1)).first;
  std::vector<double> x, y;
  auto add = [&](double c, double r) {
    const auto [px, py] = st.to_world(c, r);
    x.push_back(px), y.push_back(geographic ? std::clamp(py, -90.0, 90.0) : py);
  };
  add(0.5 * (w - 1), 0.5 * (h - 1));
  add(0.5 * (w - 1) + 1.0, 0.5 * (h - 1));
  add(0.5 * (w - 1), 0.5 * (h - 1) + 1.0);
  for (int c = 0; c <= w; ++c) add(c - 0.5, -0.5), add(c - 0.5, h - 0.5);
  for (int r = 0; r <= h; ++r) add(-0.5, r - 0.5), add(w - 0.5, r - 0.5);
  if (!transform(*to_target, x, y))
    throw DemError(path, "part of it cannot be transformed to '" + name_of(target) + "' (" +
                             gdal_message("outside the CRS's domain?") + ")");
  const double sx = std::hypot(x[1] - x[0], y[1] - y[0]), sy = std::hypot(x[2] - x[0], y[2] - y[0]);
  const auto [xmin, xmax] = std::minmax_element(x.begin() + 3, x.end());
  const auto [ymin, ymax] = std::minmax_element(y.begin() + 3, y.end());
  const double cols = std::ceil((*xmax - *xmin) / sx), rows = std::ceil((*ymax - *ymin) / sy);
  if (!(sx > 0.0) || !(sy > 0.0) || !std::isfinite(cols) || !std::isfinite(rows) || cols > double(1 << 30) ||
      rows > double(1 << 30))
    throw DemError(path,
                   "its footprint in '" + name_of(target) + "' is degenerate or over 2^30 samples a side");

  grid_.width = std::max(2, int(cols));
  grid_.height = std::max(2, int(rows));
  const double cx = 0.5 * (*xmin + *xmax), cy = 0.5 * (*ymin + *ymax);
  const double x0 = cx - 0.5 * grid_.width * sx + 0.5 * sx, y0 = cy + 0.5 * grid_.height * sy - 0.5 * sy;
  grid_.crs_transform = pm::GridTransform::north_up(x0, y0, sx, sy);
  const double k = k0 * unit;
  grid_.transform = pm::GridTransform::north_up(k * x0, k * y0, k * sx, k * sy);
  grid_.crs_wkt = wkt_of(target);
  grid_.vertical_datum = ng.vertical_datum;
  grid_.source = ng.source;
  step_ = choose_step();
  grid_.warped = true;
  grid_.frame = description + " (unit factor " + format("%.12g", unit) +
                "); warped by terralod (bilinear; positions exact every " + std::to_string(step_) +
                " samples, bilinear between them) from " + name_of(source) + ", " +
                format("%.6g", sx * unit * k0) + " x " + format("%.6g", sy * unit * k0) +
                " m cells; cells outside the source are holes";
  grid_.scale_error = scale_error_by_reads(grid_, [this](SampleRect r) { return read(r); });
  grid_.frame += scale_error_note(grid_.scale_error, automatic) + height_note;
}

void WarpedSource::positions(SampleRect window, int step, std::vector<Pos>& out) const {
  const int a0 = window.col0 / step, a1 = (window.col1 + step - 1) / step;
  const int b0 = window.row0 / step, b1 = (window.row1 + step - 1) / step;
  const std::size_t na = std::size_t(a1 - a0 + 1), nb = std::size_t(b1 - b0 + 1);
  std::vector<double> x(na * nb), y(na * nb);
  for (std::size_t j = 0; j < nb; ++j)
    for (std::size_t i = 0; i < na; ++i)
      std::tie(x[j * na + i], y[j * na + i]) =
          grid_.crs_transform->to_world(double((a0 + int(i)) * step), double((b0 + int(j)) * step));
  std::vector<int> ok(x.size(), 0);
  Transform t;
  {
    std::lock_guard lock(mutex_);
    if (!pool_.empty()) t = std::move(pool_.back()), pool_.pop_back();
  }
  if (!t) t.reset(to_native_->Clone());
  if (!t || !t->Transform(int(x.size()), x.data(), y.data(), nullptr, ok.data()))
    std::fill(ok.begin(), ok.end(), 0);
  if (t) {
    std::lock_guard lock(mutex_);
    pool_.push_back(std::move(t));
  }
  std::vector<Pos> node(x.size());
  for (std::size_t k = 0; k < x.size(); ++k) {
    if (ok[k]) {
      if (!std::isnan(native_lon_)) x[k] = native_lon_ + std::remainder(x[k] - native_lon_, 360.0);
      const auto [c, r] = native_crs_.inverse(x[k], y[k]);
      node[k] = {c, r};
    } else {
      node[k] = {kNan, kNan};
    }
  }
  // Bilinear between the nodes, from the sample's own place only (a zero weight reads nothing, so
  // the last node row or column of the window need not exist beyond it).
  const auto lerp = [](const Pos& p, const Pos& q, double t) {
    return t == 0.0 ? p : Pos{p.c + t * (q.c - p.c), p.r + t * (q.r - p.r)};
  };
  out.resize(window.samples());
  std::size_t k = 0;
  for (int j = window.row0; j <= window.row1; ++j) {
    const int b = j / step;
    const double fb = double(j - b * step) / step;
    for (int i = window.col0; i <= window.col1; ++i, ++k) {
      const int a = i / step;
      const double fa = double(i - a * step) / step;
      const std::size_t n00 = std::size_t(b - b0) * na + std::size_t(a - a0);
      const Pos top = fa == 0.0 ? node[n00] : lerp(node[n00], node[n00 + 1], fa);
      if (fb == 0.0) {
        out[k] = top;
      } else {
        const std::size_t n01 = n00 + na;
        out[k] = lerp(top, fa == 0.0 ? node[n01] : lerp(node[n01], node[n01 + 1], fa), fb);
      }
    }
  }
}

void WarpedSource::interpolate(SampleRect window, SampleRect piece, const std::vector<Pos>& pos,
                               pm::Heightfield& b, std::vector<std::uint8_t>& mask) const {
  const std::size_t ww = std::size_t(window.width());
  const auto at = [&](int i, int j) {
    return std::size_t(j - window.row0) * ww + std::size_t(i - window.col0);
  };
  // The native cell (i0, j0) .. (i0 + 1, j0 + 1) of a position, clamped to the grid.
  const auto cell = [](double v, int n) {
    const double c = std::clamp(v, 0.0, double(n - 1));
    const int i0 = std::min(int(std::floor(c)), std::max(0, n - 2));
    return std::pair{i0, c - i0};
  };
  SampleRect src{nw_, nh_, -1, -1};
  for (int j = piece.row0; j <= piece.row1; ++j)
    for (int i = piece.col0; i <= piece.col1; ++i) {
      const Pos& p = pos[at(i, j)];
      if (!std::isfinite(p.c) || !std::isfinite(p.r)) continue;
      const int c0 = cell(p.c, nw_).first, r0 = cell(p.r, nh_).first;
      src = {std::min(src.col0, c0), std::min(src.row0, r0), std::max(src.col1, std::min(nw_ - 1, c0 + 1)),
             std::max(src.row1, std::min(nh_ - 1, r0 + 1))};
    }
  if (src.col1 < 0) {  // no position: holes of height 0
    for (int j = piece.row0; j <= piece.row1; ++j)
      for (int i = piece.col0; i <= piece.col1; ++i) b.samples()[at(i, j)] = 0.0, mask[at(i, j)] = 0;
    return;
  }
  if (piece.samples() > 1 && src.samples() > 4 * piece.samples() + 1024) {
    SampleRect first = piece, second = piece;
    if (piece.width() >= piece.height()) {
      first.col1 = piece.col0 + piece.width() / 2 - 1, second.col0 = first.col1 + 1;
    } else {
      first.row1 = piece.row0 + piece.height() / 2 - 1, second.row0 = first.row1 + 1;
    }
    interpolate(window, first, pos, b, mask);
    interpolate(window, second, pos, b, mask);
    return;
  }
  const pm::Heightfield s = native_->read(src);
  const std::size_t sw = std::size_t(s.width());
  for (int j = piece.row0; j <= piece.row1; ++j)
    for (int i = piece.col0; i <= piece.col1; ++i) {
      const std::size_t k = at(i, j);
      const Pos& p = pos[k];
      if (!std::isfinite(p.c) || !std::isfinite(p.r)) {
        b.samples()[k] = 0.0, mask[k] = 0;
        continue;
      }
      const bool outside = p.c < -0.5 || p.c > nw_ - 0.5 || p.r < -0.5 || p.r > nh_ - 0.5;
      const auto [c0, fx] = cell(p.c, nw_);
      const auto [r0, fy] = cell(p.r, nh_);
      const std::size_t i0 = std::size_t(c0 - src.col0),
                        i1 = std::size_t(std::min(nw_ - 1, c0 + 1) - src.col0);
      const std::size_t j0 = std::size_t(r0 - src.row0),
                        j1 = std::size_t(std::min(nh_ - 1, r0 + 1) - src.row0);
      const std::size_t corner[4] = {j0 * sw + i0, j0 * sw + i1, j1 * sw + i0, j1 * sw + i1};
      const double weight[4] = {(1.0 - fx) * (1.0 - fy), fx * (1.0 - fy), (1.0 - fx) * fy, fx * fy};
      bool hole = false;
      for (int q = 0; q < 4; ++q) hole = hole || (weight[q] > 0.0 && !s.valid(corner[q]));
      const std::vector<double>& z = s.samples();
      double v = 0.0;
      if (!hole) {
        const auto lerp = [](double u, double w, double t) { return t == 0.0 ? u : u + t * (w - u); };
        v = lerp(lerp(z[corner[0]], z[corner[1]], fx), lerp(z[corner[2]], z[corner[3]], fx), fy);
      } else {  // the valid neighbours' weighted mean, or 0
        double sum = 0.0, total = 0.0;
        for (int q = 0; q < 4; ++q)
          if (weight[q] > 0.0 && s.valid(corner[q])) sum += weight[q] * z[corner[q]], total += weight[q];
        v = total > 0.0 ? sum / total : 0.0;
      }
      // + 0.0: never -0.0, which a PM cannot store as an integer multiple (pm_io.cpp).
      b.samples()[k] = std::ldexp(std::nearbyint(std::ldexp(v, kHeightBits)), -kHeightBits) + 0.0;
      mask[k] = (hole || outside) ? 0 : 1;
    }
}

int WarpedSource::choose_step() const {
  const int w = grid_.width, h = grid_.height;
  for (int step = 16; step > 1; step /= 2) {
    if (step >= w || step >= h) continue;
    double worst = 0.0;
    std::vector<Pos> exact, lerped;
    for (int gj = 0; gj <= 4 && worst <= kPositionTolerance; ++gj)
      for (int gi = 0; gi <= 4 && worst <= kPositionTolerance; ++gi) {
        // The cell of the lattice of `step` nearest to this point of a 5 x 5 spread.
        const int c0 = std::min((w - 1 - step) / step, (w - 1) * gi / 4 / step) * step;
        const int r0 = std::min((h - 1 - step) / step, (h - 1) * gj / 4 / step) * step;
        const SampleRect cell{c0, r0, c0 + step, r0 + step};
        positions(cell, 1, exact);
        positions(cell, step, lerped);
        for (std::size_t k = 0; k < exact.size(); ++k) {
          const double d = std::max(std::abs(exact[k].c - lerped[k].c), std::abs(exact[k].r - lerped[k].r));
          worst = std::isfinite(d) ? std::max(worst, d) : (std::isfinite(exact[k].c) ? 1e300 : worst);
        }
      }
    if (worst <= kPositionTolerance) return step;
  }
  return 1;
}

pm::Heightfield WarpedSource::read(SampleRect window) const {
  check_window(window, path_);
  std::vector<Pos> pos;
  positions(window, step_, pos);
  pm::Heightfield b(window.width(), window.height());
  std::vector<std::uint8_t> mask(b.size(), 1);
  interpolate(window, window, pos, b, mask);
  if (std::find(mask.begin(), mask.end(), 0) != mask.end()) b.set_mask(std::move(mask));
  describe(b, window);
  return b;
}

std::uint32_t WarpedSource::samples_crc() const {
  const std::size_t width = std::size_t(grid_.width);
  SampleCrc crc;
  for_each_band(*this, [&](int, const pm::Heightfield& b) {
    for (std::size_t at = 0; at < b.size(); at += width)
      crc.add_row(b.samples().data() + at, b.has_holes() ? b.mask().data() + at : nullptr, width);
  });
  return crc.value();
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
  const pm::VoidReport voids = hf.voids;
  const std::unique_ptr<DemSource> warped = warped_source(path, heightfield_source(std::move(hf)), crs, "");
  const DemGrid& g = warped->grid();
  if (g.samples() > (std::uint64_t(1) << 30))
    throw DemError(path,
                   "its footprint in its world frame is over 2^30 samples, more than a grid held in memory "
                   "may have (build reads it window by window: open_dem_source)");
  pm::Heightfield r(g.width, g.height);
  std::vector<std::uint8_t> mask(r.size(), 1);
  std::size_t holes = 0;
  for_each_band(*warped, [&](int r0, const pm::Heightfield& b) {
    const std::size_t at = std::size_t(r0) * std::size_t(g.width);
    std::copy(b.samples().begin(), b.samples().end(), r.samples().begin() + std::ptrdiff_t(at));
    for (std::size_t i = 0; i < b.size(); ++i)
      if (!b.valid(i)) mask[at + i] = 0, ++holes;
  });
  if (holes == r.size()) throw DemError(path, "no sample is left after warping it to its world frame");
  if (holes > 0) r.set_mask(std::move(mask));
  r.transform = g.transform;
  r.crs_transform = g.crs_transform;
  r.crs_wkt = g.crs_wkt;
  r.voids = voids;
  r.vertical_datum = g.vertical_datum;
  r.source = g.source;
  r.frame = g.frame;
  return r;
}

std::optional<double> scale_error_by_reads(const DemGrid& grid,
                                           const std::function<pm::Heightfield(SampleRect)>& read) {
  const int width = grid.width, height = grid.height;
  if (grid.crs_wkt.empty() || !grid.crs_transform) return std::nullopt;
  constexpr int kStrip = 4096;
  struct Ends {
    int row0 = -1;
    std::vector<std::uint8_t> left, right;
  } ends;
  // Segments from the row's end, 256 samples first (a row's valid samples usually start within a
  // few of its end: a warped frame's slanted edges), doubling up to kStrip.
  auto first_valid = [&](int r, bool from_left) {
    for (int k = 0, len = 256; k < width; k += len, len = std::min(kStrip, 2 * len)) {
      const int c0 = from_left ? k : std::max(0, width - k - len),
                c1 = from_left ? std::min(width, k + len) - 1 : width - k - 1;
      const pm::Heightfield b = read({c0, r, c1, r});
      for (int i = 0; i < b.width(); ++i) {
        const int j = from_left ? i : b.width() - 1 - i;
        if (b.valid(std::size_t(j))) return c0 + j;
      }
    }
    return from_left ? width : -1;
  };
  return scale_error(
      grid.crs_wkt, grid.crs_transform, grid.transform, width, height,
      [&](int c, int r) {
        return !read({c, r, c, r}).has_holes();
      },
      [&](int r) {
        if (r < ends.row0 || r >= ends.row0 + int(ends.left.size())) {
          ends.row0 = r;
          const int r1 = std::min(height, r + kStrip) - 1;
          const pm::Heightfield left = read({0, r, 0, r1}), right = read({width - 1, r, width - 1, r1});
          ends.left.assign(std::size_t(r1 - r + 1), 1);
          ends.right = ends.left;
          for (int i = 0; i <= r1 - r; ++i) {
            ends.left[std::size_t(i)] = left.valid(std::size_t(i)) ? 1 : 0;
            ends.right[std::size_t(i)] = right.valid(std::size_t(i)) ? 1 : 0;
          }
        }
        const std::size_t i = std::size_t(r - ends.row0);
        const int first = ends.left[i] ? 0 : first_valid(r, true);
        if (first == width) return std::pair{width, width - 1};
        return std::pair{first, ends.right[i] ? width - 1 : first_valid(r, false)};
      });
}

std::unique_ptr<DemSource> warped_source(const std::string& path, std::unique_ptr<DemSource> native,
                                         const std::string& crs, const std::string& height_note) {
  register_gdal();
  QuietGdal quiet;
  const DemGrid& ng = native->grid();
  const OGRSpatialReference source = warp_source_crs(path, ng, crs);
  std::optional<AutoFrame> frame;
  if (crs == "auto") {
    frame = auto_frame(path, source, *ng.crs_transform, ng.width, ng.height, *native);
    if (frame->error > kFlatFrameLimit)
      return std::make_unique<NativeKept>(std::move(native), *frame, height_note);
  }
  return std::make_unique<WarpedSource>(path, std::move(native), crs, height_note, source, std::move(frame));
}

}  // namespace detail

}  // namespace terralod::blocks
