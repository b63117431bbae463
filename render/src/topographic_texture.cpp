// CPU generator of topographic (shading) textures: Horn normals, Lambert / Phong /
// multidirectional / relative-height shading and self-shadowing by grid-line ray marching.
//
// Formulas and references: render/include/terralod/render/topographic_texture.hpp (Horn 1981;
// Mark 1992 / GDAL gdaldem -multidirectional; Döllner et al. shading textures, self-shadowing by
// rays toward the light against the full-resolution terrain). GL-free: no GL header here.
// Memory: the output raster, plus two float rasters (row-wise min and max) for RelativeHeight.
// The GPU twin (gpu_shading.cpp) evaluates the same expressions in the same order.
#include "terralod/render/topographic_texture.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "shading_common.hpp"
#include "terralod/pm/parallel.hpp"

namespace terralod::render {

ShadingMethod parse_shading_method(const std::string& name) {
  if (name == "lambert") return ShadingMethod::Lambert;
  if (name == "phong") return ShadingMethod::Phong;
  if (name == "multidirectional") return ShadingMethod::Multidirectional;
  if (name == "relative") return ShadingMethod::RelativeHeight;
  throw std::invalid_argument("unknown shading method '" + name +
                              "' (expected lambert, phong, multidirectional or relative)");
}

const char* shading_method_name(ShadingMethod m) {
  switch (m) {
    case ShadingMethod::Lambert:
      return "lambert";
    case ShadingMethod::Phong:
      return "phong";
    case ShadingMethod::Multidirectional:
      return "multidirectional";
    case ShadingMethod::RelativeHeight:
      return "relative";
  }
  return "?";
}

void TexelRegion::check(int full_width, int full_height, const char* what) const {
  auto bad = [&](const std::string& m) {
    throw std::invalid_argument(std::string(what) + ": texel region " + m);
  };
  if (step < 1) bad("step " + std::to_string(step) + " < 1");
  if (col0 < 0 || row0 < 0 || col0 >= full_width || row0 >= full_height)
    bad("origin (" + std::to_string(col0) + ", " + std::to_string(row0) + ") outside the " +
        std::to_string(full_width) + " x " + std::to_string(full_height) + " grid");
  const int c = cols_in(full_width), r = rows_in(full_height);
  if (c < 1 || r < 1 || col0 + c > full_width || row0 + r > full_height)
    bad(std::to_string(c) + " x " + std::to_string(r) + " samples at (" + std::to_string(col0) + ", " +
        std::to_string(row0) + ") do not fit the " + std::to_string(full_width) + " x " +
        std::to_string(full_height) + " grid");
}

Vec3d light_direction(double azimuth_deg, double altitude_deg) {
  const double a = azimuth_deg * std::numbers::pi / 180.0, h = altitude_deg * std::numbers::pi / 180.0;
  return {std::sin(a) * std::cos(h), std::cos(a) * std::cos(h), std::sin(h)};
}

namespace detail {

void validate_shading(const pm::Heightfield& hf, const ShadingOptions& o, const TexelRegion& region,
                      const char* what) {
  auto bad = [&](const std::string& m) { throw std::invalid_argument(std::string(what) + ": " + m); };
  if (hf.width() < 1 || hf.height() < 1) bad("empty heightfield");
  region.check(hf.width(), hf.height(), what);
  validate_shading_options(o, hf.transform, what);
}

void validate_shading_options(const ShadingOptions& o, const pm::GridTransform& transform, const char* what) {
  auto bad = [&](const std::string& m) { throw std::invalid_argument(std::string(what) + ": " + m); };
  if (!(o.altitude_deg > 0.0 && o.altitude_deg <= 90.0))
    bad("light altitude " + std::to_string(o.altitude_deg) + " is outside (0, 90] degrees");
  if (!std::isfinite(o.azimuth_deg)) bad("light azimuth is not finite");
  if (!(o.vertical_exaggeration > 0.0) || !std::isfinite(o.vertical_exaggeration))
    bad("vertical exaggeration must be > 0");
  if (!(o.ambient >= 0.0 && o.ambient <= 1.0)) bad("ambient must be in [0, 1]");
  if (!(o.shadow_bias >= 0.0)) bad("shadow bias must be >= 0");
  if (!(o.phong_ka >= 0 && o.phong_kd >= 0 && o.phong_ks >= 0 && o.phong_shininess >= 0))
    bad("Phong constants must be >= 0");
  if (o.method == ShadingMethod::Multidirectional) {
    if (o.multidirectional_azimuths.empty()) bad("multidirectional shading needs at least one azimuth");
    for (double a : o.multidirectional_azimuths)
      if (!std::isfinite(a)) bad("multidirectional azimuth is not finite");
  }
  if (o.relative_radius < 0) bad("relative radius must be >= 0");
  if (o.shadows && o.method == ShadingMethod::RelativeHeight)
    bad("shadows apply to lit methods only, not to relative-height shading");
  if (o.threads < 0) bad("threads must be >= 0");
  const double det = transform.determinant();
  if (!(std::abs(det) > 0.0) || !std::isfinite(det)) bad("grid transform is singular");
}

GridFrame::GridFrame(const pm::Heightfield& hf, double exaggeration)
    : hf_(&hf), w_(hf.width()), h_(hf.height()) {
  const auto& t = hf.transform;
  const double det = t.determinant();
  // [gx, gy] = J^-T [gc, gr], J = [[xc, xr], [yc, yr]].
  m00 = t.yr / det, m01 = -t.yc / det, m10 = -t.xr / det, m11 = t.xc / det;
  // Grid direction of a world horizontal unit vector: u = J^-1 d.
  i00 = t.yr / det, i01 = -t.xr / det, i10 = -t.yc / det, i11 = t.xc / det;
  ez = exaggeration;
}

void GridFrame::build_shadow_index() {
  // Block (bx, by) holds the samples of columns [bx*B, bx*B + B] and rows [by*B, by*B + B]:
  // a sample on a block boundary counts for both blocks beside it.
  bw_ = std::max(1, (w_ - 1 + kBlock - 1) / kBlock);
  bh_ = std::max(1, (h_ - 1 + kBlock - 1) / kBlock);
  zmax = -std::numeric_limits<double>::infinity();
  bmax_.assign(std::size_t(bw_) * bh_, -std::numeric_limits<double>::infinity());
  for (int r = 0; r < h_; ++r)
    for (int c = 0; c < w_; ++c) {
      if (!hf_->valid(c, r)) continue;
      const double z = hf_->at(c, r) * ez;
      zmax = std::max(zmax, z);
      const int bx1 = std::min(c / kBlock, bw_ - 1), by1 = std::min(r / kBlock, bh_ - 1);
      const int bx0 = (c % kBlock == 0 && c > 0) ? c / kBlock - 1 : bx1;
      const int by0 = (r % kBlock == 0 && r > 0) ? r / kBlock - 1 : by1;
      for (int by = by0; by <= by1; ++by)
        for (int bx = bx0; bx <= bx1; ++bx) {
          double& m = bmax_[std::size_t(by) * bw_ + bx];
          m = std::max(m, z);
        }
    }
}

}  // namespace detail

Vec3d horn_normal(const pm::Heightfield& hf, int col, int row, double vertical_exaggeration) {
  assert(col >= 0 && col < hf.width() && row >= 0 && row < hf.height());
  const detail::GridFrame f(hf, vertical_exaggeration);
  double gx, gy;
  f.gradient(col, row, gx, gy);
  const double n = std::sqrt(1.0 + gx * gx + gy * gy);
  return {-gx / n, -gy / n, 1.0 / n};
}

namespace {

using detail::GridFrame;

struct LightSet {
  std::vector<Vec3d> l;        // unit light vectors
  std::vector<double> ux, uy;  // grid direction per horizontal metre toward each light
  std::vector<double> dx, dy;  // horizontal unit direction (sin A, cos A)
  double tan_h = 1.0;
};

LightSet make_lights(const GridFrame& f, const ShadingOptions& o) {
  LightSet s;
  std::vector<double> az;
  if (o.method == ShadingMethod::Multidirectional)
    az = o.multidirectional_azimuths;
  else
    az = {o.azimuth_deg};
  const double h = o.altitude_deg * std::numbers::pi / 180.0;
  s.tan_h = std::tan(h);
  for (double a : az) {
    s.l.push_back(light_direction(a, o.altitude_deg));
    const double ar = a * std::numbers::pi / 180.0;
    const double sx = std::sin(ar), sy = std::cos(ar);
    s.dx.push_back(sx), s.dy.push_back(sy);
    double ux, uy;
    f.grid_direction(sx, sy, ux, uy);
    s.ux.push_back(ux), s.uy.push_back(uy);
  }
  return s;
}

// Row-wise running min/max over [c - R, c + R] for rows [r_lo, r_hi] at the texel columns.
struct RelativeWindow {
  int r_lo = 0;
  int out_w = 0;
  std::vector<float> mn, mx;  // (rows) x out_w
};

}  // namespace

namespace detail {

FloatRaster shade_window(const pm::Heightfield& hf, const ShadingOptions& o, const TexelRegion& region,
                         const WindowPlace& place) {
  detail::validate_shading(hf, o, region, "shade_terrain");
  const int W = hf.width(), H = hf.height();
  const int ow = region.out_width(W), oh = region.out_height(H);
  FloatRaster out(ow, oh);
  GridFrame f(hf, o.vertical_exaggeration);
  f.place(place.col0, place.row0);
  if (o.shadows) f.build_shadow_index();
  const LightSet lights = make_lights(f, o);

  // Relative height: zmin/zmax per texel (global range or separable window).
  double gmin = std::numeric_limits<double>::infinity(), gmax = -gmin;
  RelativeWindow win;
  const int R = o.relative_radius;
  if (o.method == ShadingMethod::RelativeHeight) {
    if (R == 0 && place.has_range) {
      if (place.lo <= place.hi) gmin = place.lo * f.ez, gmax = place.hi * f.ez;
    } else if (R == 0) {
      for (std::size_t i = 0; i < hf.size(); ++i)
        if (hf.valid(i)) gmin = std::min(gmin, hf[i] * f.ez), gmax = std::max(gmax, hf[i] * f.ez);
    } else {
      const int last_row = region.row0 + (oh - 1) * region.step;
      win.r_lo = std::max(0, region.row0 - R);
      const int r_hi = std::min(H - 1, last_row + R);
      win.out_w = ow;
      const std::size_t n = std::size_t(r_hi - win.r_lo + 1) * ow;
      win.mn.assign(n, std::numeric_limits<float>::infinity());
      win.mx.assign(n, -std::numeric_limits<float>::infinity());
      for (int r = win.r_lo; r <= r_hi; ++r)
        for (int i = 0; i < ow; ++i) {
          const int c = region.col0 + i * region.step;
          float mn = std::numeric_limits<float>::infinity(), mx = -mn;
          for (int k = std::max(0, c - R); k <= std::min(W - 1, c + R); ++k)
            if (hf.valid(k, r)) {
              const float z = static_cast<float>(hf.at(k, r) * f.ez);
              mn = std::min(mn, z), mx = std::max(mx, z);
            }
          win.mn[std::size_t(r - win.r_lo) * ow + i] = mn;
          win.mx[std::size_t(r - win.r_lo) * ow + i] = mx;
        }
    }
  }

  auto shade_row = [&](int j) {
    const int row = region.row0 + j * region.step;
    for (int i = 0; i < ow; ++i) {
      const int col = region.col0 + i * region.step;
      float& dst = out.v[std::size_t(j) * ow + i];
      if (!hf.valid(col, row)) {
        dst = std::numeric_limits<float>::quiet_NaN();
        continue;
      }
      if (o.method == ShadingMethod::RelativeHeight) {
        double zmin = gmin, zmax = gmax;
        if (R > 0) {
          float mn = std::numeric_limits<float>::infinity(), mx = -mn;
          for (int r = std::max(0, row - R); r <= std::min(H - 1, row + R); ++r) {
            const std::size_t k = std::size_t(r - win.r_lo) * ow + i;
            mn = std::min(mn, win.mn[k]), mx = std::max(mx, win.mx[k]);
          }
          zmin = mn, zmax = mx;
        }
        const double z = R > 0 ? double(static_cast<float>(hf.at(col, row) * f.ez)) : hf.at(col, row) * f.ez;
        dst = zmax > zmin ? static_cast<float>((z - zmin) / (zmax - zmin)) : 0.5f;
        continue;
      }
      double gx, gy;
      f.gradient(col, row, gx, gy);
      const double len = std::sqrt(1.0 + gx * gx + gy * gy);
      const Vec3d n{-gx / len, -gy / len, 1.0 / len};
      auto lit = [&](std::size_t k) {
        return !o.shadows || !f.shadowed(col, row, lights.ux[k], lights.uy[k], lights.tan_h, o.shadow_bias);
      };
      double value = 0.0;
      if (o.method == ShadingMethod::Multidirectional) {
        const double g2 = gx * gx + gy * gy;
        double sw = 0.0, sd = 0.0;
        for (std::size_t k = 0; k < lights.l.size(); ++k) {
          const double gd = gx * lights.dx[k] + gy * lights.dy[k];
          const double w = g2 > 0.0 ? gd * gd / g2 : 1.0;
          const Vec3d& l = lights.l[k];
          const double nl = n.x * l.x + n.y * l.y + n.z * l.z;
          const double d = (nl > 0.0 && lit(k)) ? nl : 0.0;
          sw += w, sd += w * d;
        }
        value = o.ambient + (1.0 - o.ambient) * (sw > 0.0 ? sd / sw : 0.0);
      } else {
        const Vec3d& l = lights.l[0];
        const double nl = n.x * l.x + n.y * l.y + n.z * l.z;
        const bool on = nl > 0.0 && lit(0);
        const double d = on ? nl : 0.0;
        if (o.method == ShadingMethod::Lambert) {
          value = o.ambient + (1.0 - o.ambient) * d;
        } else {  // Phong, viewer at (0, 0, 1): r.v = 2 (n.l) n_z - l_z
          const double rv = 2.0 * nl * n.z - l.z;
          const double s = (on && rv > 0.0) ? std::pow(rv, o.phong_shininess) : 0.0;
          value = std::min(1.0, o.phong_ka + o.phong_kd * d + o.phong_ks * s);
        }
      }
      dst = static_cast<float>(value);
    }
  };

  // Rows handed out one at a time balance the shadow cost, which varies with the relief.
  pm::parallel_for(std::size_t(oh), o.threads, [&](std::size_t j) { shade_row(int(j)); });
  return out;
}

}  // namespace detail

FloatRaster shade_terrain(const pm::Heightfield& hf, const ShadingOptions& o, const TexelRegion& region) {
  return detail::shade_window(hf, o, region, {});
}

RgbaImage shading_texture(const pm::Heightfield& hf, const ShadingOptions& options,
                          const TexelRegion& region) {
  return grey_to_rgba(shade_terrain(hf, options, region));
}

}  // namespace terralod::render
