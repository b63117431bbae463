// Private helpers shared by the CPU shading and thematic generators: Horn gradients in the world
// frame and the grid-line shadow march (formulas in topographic_texture.hpp). GL-free.
#pragma once

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <vector>

#include "terralod/pm/heightfield.hpp"
#include "terralod/render/topographic_texture.hpp"

namespace terralod::render::detail {

/// Throws std::invalid_argument("<what>: ...") for bad options or region (see the header).
void validate_shading(const pm::Heightfield& hf, const ShadingOptions& o, const TexelRegion& region,
                      const char* what);
/// The option checks alone, for a grid with `transform`.
void validate_shading_options(const ShadingOptions& o, const pm::GridTransform& transform, const char* what);

/// Where a heightfield lies in a larger grid (terrain_windows.hpp): its sample (0, 0) is the
/// grid's (col0, row0); with has_range, lo..hi is the grid's exact height range (what
/// RelativeHeight with radius 0 spans).
struct WindowPlace {
  int col0 = 0, row0 = 0;
  bool has_range = false;
  double lo = 0, hi = 0;
};

/// shade_terrain of `hf` placed in its larger grid: the larger grid's values wherever the
/// window holds what each texel reaches (shade_terrain is this with the default place).
FloatRaster shade_window(const pm::Heightfield& hf, const ShadingOptions& o, const TexelRegion& region,
                         const WindowPlace& place);

/// The heightfield seen through its GridTransform, with vertical exaggeration `ez`.
class GridFrame {
 public:
  GridFrame(const pm::Heightfield& hf, double exaggeration);

  /// The heightfield is the window of a larger grid whose sample (col0, row0) is its (0, 0):
  /// shadow rays are then followed in the larger grid's indices, so that a window's rays cross
  /// the grid lines at the very same floating-point positions as the whole grid's
  /// (terrain_windows.hpp).
  void place(int col0, int row0) { oc_ = col0, or_ = row0; }

  /// Height at a clamped index; a hole reads as `fallback`.
  double z(int c, int r, double fallback) const {
    c = std::clamp(c, 0, w_ - 1), r = std::clamp(r, 0, h_ - 1);
    return hf_->valid(c, r) ? hf_->at(c, r) * ez : fallback;
  }

  /// Horn gradient (dz/dx east, dz/dy north) at sample (c, r), edge replication.
  void gradient(int c, int r, double& gx, double& gy) const {
    const double e = hf_->valid(c, r) ? hf_->at(c, r) * ez : 0.0;
    const double a = z(c - 1, r - 1, e), b = z(c, r - 1, e), cc = z(c + 1, r - 1, e);
    const double d = z(c - 1, r, e), f = z(c + 1, r, e);
    const double g = z(c - 1, r + 1, e), h = z(c, r + 1, e), i = z(c + 1, r + 1, e);
    const double gc = ((cc + 2.0 * f + i) - (a + 2.0 * d + g)) / 8.0;
    const double gr = ((g + 2.0 * h + i) - (a + 2.0 * b + cc)) / 8.0;
    gx = m00 * gc + m01 * gr;
    gy = m10 * gc + m11 * gr;
  }

  /// Grid step (dcol, drow) per metre along the world horizontal direction (sx, sy).
  void grid_direction(double sx, double sy, double& uc, double& ur) const {
    uc = i00 * sx + i01 * sy;
    ur = i10 * sx + i11 * sy;
  }

  /// Computes zmax and the block maxima the shadow march uses; call once before shadowed().
  void build_shadow_index();

  /// True when a ray from sample (c0, r0) along grid direction (uc, ur) per metre, climbing
  /// tan_h metres per metre, passes below the surface by more than `bias` at a grid-line crossing.
  ///
  /// Acceleration (the answer is the plain march's): the grid is cut into blocks of kBlock x
  /// kBlock cells whose maxima include their boundary lines. Where the ray enters a block above
  /// that block's maximum, no crossing inside the block (boundary lines included) can be above
  /// the ray, since the ray only rises: the march jumps to the block's exit.
  bool shadowed(int c0, int r0, double uc, double ur, double tan_h, double bias) const {
    assert(!bmax_.empty());
    const double z0 = hf_->at(c0, r0) * ez;
    const double ca = double(c0 + oc_), ra = double(r0 + or_);  // the start in the larger grid
    const double inf = std::numeric_limits<double>::infinity();
    const int sc = uc > 0 ? 1 : -1, sr = ur > 0 ? 1 : -1;
    const double dtc = uc != 0.0 ? 1.0 / std::abs(uc) : inf;
    const double dtr = ur != 0.0 ? 1.0 / std::abs(ur) : inf;
    int nc = 1, nr = 1;         // index of the next column / row line crossed
    double t_prev = 0.0;        // parameter of the last crossing passed
    double t_block_end = -1.0;  // exit parameter of the block checked last
    // First index n >= n0 whose crossing n * dt is not below ts.
    auto first_not_below = [](int n0, double dt, double ts) {
      int n = std::max(n0, static_cast<int>(std::min(ts / dt, 2e9)));
      while (n > n0 && (n - 1) * dt >= ts) --n;
      while (n * dt < ts) ++n;
      return n;
    };
    for (;;) {
      const double tc = nc * dtc, tr = nr * dtr;
      const double t = std::min(tc, tr);
      if (!(t < inf)) return false;
      if (t_prev >= t_block_end) {
        // The ray between t_prev and t stays in one cell; check that cell's block once.
        const double tm = 0.5 * (t_prev + t);
        const int cell_c =
            std::clamp(static_cast<int>(std::floor(ca + tm * uc)) - oc_, 0, std::max(0, w_ - 2));
        const int cell_r =
            std::clamp(static_cast<int>(std::floor(ra + tm * ur)) - or_, 0, std::max(0, h_ - 2));
        const int bx = std::min(cell_c / kBlock, bw_ - 1), by = std::min(cell_r / kBlock, bh_ - 1);
        const double ec = uc != 0.0 ? ((uc > 0 ? (bx + 1) * kBlock : bx * kBlock) - c0) / uc : inf;
        const double er = ur != 0.0 ? ((ur > 0 ? (by + 1) * kBlock : by * kBlock) - r0) / ur : inf;
        t_block_end = std::min(ec, er);
        if (z0 + t_prev * tan_h > bmax_[std::size_t(by) * bw_ + bx]) {
          // Skip every crossing a hair before the exit; the boundary crossing is tested.
          const double ts = t_block_end * (1.0 - 1e-12);
          const int nc2 = dtc < inf ? first_not_below(nc, dtc, ts) : nc;
          const int nr2 = dtr < inf ? first_not_below(nr, dtr, ts) : nr;
          if (nc2 != nc || nr2 != nr) {
            t_prev = std::max(nc2 > nc ? (nc2 - 1) * dtc : 0.0, nr2 > nr ? (nr2 - 1) * dtr : 0.0);
            nc = nc2, nr = nr2;
            continue;
          }
        }
      }
      const bool col_line = tc <= tr;
      const double ray = z0 + t * tan_h;
      if (ray > zmax) return false;
      double terrain;
      bool have;
      if (col_line) {
        const int k = c0 + sc * nc;
        if (k < 0 || k >= w_) return false;
        const double rr = ra + t * ur;
        if (rr < or_ || rr > or_ + h_ - 1) return false;
        have = line_height(k, rr, or_, /*along_column=*/true, terrain);
        ++nc;
      } else {
        const int k = r0 + sr * nr;
        if (k < 0 || k >= h_) return false;
        const double cc = ca + t * uc;
        if (cc < oc_ || cc > oc_ + w_ - 1) return false;
        have = line_height(k, cc, oc_, /*along_column=*/false, terrain);
        ++nr;
      }
      t_prev = t;
      if (have && terrain - ray > bias) return true;
    }
  }

  static constexpr int kBlock = 16;  ///< cells per block edge of the shadow index
  double ez = 1.0;
  double zmax = 0.0;  ///< highest valid sample times ez (after build_shadow_index)
  int blocks_x() const { return bw_; }
  int blocks_y() const { return bh_; }
  const std::vector<double>& block_max() const { return bmax_; }

 private:
  // Height on grid line k at fractional position s along it (linear between two samples); s
  // counts from `offset` samples before the heightfield's first (place()).
  bool line_height(int k, double s, int offset, bool along_column, double& out) const {
    const int s_grid = static_cast<int>(std::floor(s));
    const int s0 = s_grid - offset;
    const int n = along_column ? h_ : w_;
    const int s1 = std::min(s0 + 1, n - 1);
    const double fr = s - s_grid;
    const int c0 = along_column ? k : s0, r0 = along_column ? s0 : k;
    const int c1 = along_column ? k : s1, r1 = along_column ? s1 : k;
    if (!hf_->valid(c0, r0) || !hf_->valid(c1, r1)) return false;
    const double z0 = hf_->at(c0, r0) * ez, z1 = hf_->at(c1, r1) * ez;
    out = z0 + (z1 - z0) * fr;
    return true;
  }

  const pm::Heightfield* hf_;
  int w_, h_;
  int oc_ = 0, or_ = 0;  // place()
  int bw_ = 0, bh_ = 0;
  std::vector<double> bmax_;  // block maxima (boundary lines included), -inf where all holes
  double m00, m01, m10, m11;  // J^-T
  double i00, i01, i10, i11;  // J^-1
};

}  // namespace terralod::render::detail
