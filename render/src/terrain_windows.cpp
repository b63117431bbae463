// Texel regions of a terrain computed window by window (terrain_windows.hpp).
#include "terralod/render/terrain_windows.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "shading_common.hpp"
#include "terralod/blocks/database_terrain.hpp"

namespace terralod::render {

TerrainWindows terrain_windows(blocks::DatabaseTerrain& terrain,
                               const std::function<void(double)>& progress) {
  TerrainWindows t;
  t.width = terrain.width(), t.height = terrain.height();
  t.transform = terrain.frame().transform;
  if (const std::optional<blocks::HeightRange> r = terrain.height_range(progress))
    t.lo = r->lo, t.hi = r->hi;
  else
    t.lo = 1, t.hi = 0;
  t.read = [&terrain](int col0, int row0, int cols, int rows) {
    return terrain.read({col0, row0, col0 + cols - 1, row0 + rows - 1});
  };
  return t;
}

namespace {

// A raster's texels as bytes: FloatRaster one float each, RgbaImage four bytes.
std::uint8_t* texel_bytes(FloatRaster& r) { return reinterpret_cast<std::uint8_t*>(r.v.data()); }
std::uint8_t* texel_bytes(RgbaImage& r) { return r.rgba.data(); }
const std::uint8_t* texel_bytes(const FloatRaster& r) {
  return reinterpret_cast<const std::uint8_t*>(r.v.data());
}
const std::uint8_t* texel_bytes(const RgbaImage& r) { return r.rgba.data(); }

// compute_by_windows for rasters of either kind. A tile's region in its window covers whole
// step x step blocks (clipped at the region's edge), so a rule that reduces blocks sees them all.
template <class Raster, class Compute>
Raster by_windows(const TerrainWindows& t, const TexelRegion& region, const WindowMargins& m,
                  const Compute& compute) {
  region.check(t.width, t.height, "compute_by_windows");
  const int s = region.step, ow = region.out_width(t.width), oh = region.out_height(t.height);
  const int c_stop = region.col0 + region.cols_in(t.width), r_stop = region.row0 + region.rows_in(t.height);
  Raster out(ow, oh);
  constexpr std::size_t bytes = std::is_same_v<Raster, RgbaImage> ? 4 : sizeof(float);
  // Square tiles of about window_samples samples, widened where the margins leave few columns.
  const double ws = double(std::max<std::size_t>(t.window_samples, 1));
  const int side = std::max(64, int(std::sqrt(ws)));
  const int n = std::max(1, side / s);
  // Texels whose samples and margins fit `max_side` along one axis (at least one texel).
  const auto fit = [&](int texels, int margins) {
    return t.max_side > 0 ? std::max(1, std::min(texels, (t.max_side - margins) / s)) : texels;
  };
  const int tr = fit(std::min(oh, n), m.top + m.bottom);
  const double rows_read = double(tr) * s + m.top + m.bottom;
  const int wide = int(std::min(double(ow), (ws / rows_read - m.left - m.right) / s));
  const int tc = fit(std::min(ow, std::max(n, wide)), m.left + m.right);
  for (int j0 = 0; j0 < oh; j0 += tr)
    for (int i0 = 0; i0 < ow; i0 += tc) {
      const int cols = std::min(tc, ow - i0), rows = std::min(tr, oh - j0);
      const int c_first = region.col0 + i0 * s, c_end = std::min(c_first + cols * s, c_stop);
      const int r_first = region.row0 + j0 * s, r_end = std::min(r_first + rows * s, r_stop);
      const int wc0 = std::max(0, c_first - m.left), wc1 = std::min(t.width - 1, c_end - 1 + m.right);
      const int wr0 = std::max(0, r_first - m.top), wr1 = std::min(t.height - 1, r_end - 1 + m.bottom);
      const pm::Heightfield window = t.read(wc0, wr0, wc1 - wc0 + 1, wr1 - wr0 + 1);
      const TexelRegion in{c_first - wc0, r_first - wr0, c_end - c_first, r_end - r_first, s};
      const Raster tile = compute(window, in, wc0, wr0);
      if (tile.width != cols || tile.height != rows)
        throw std::logic_error("compute_by_windows: a tile of " + std::to_string(cols) + " x " +
                               std::to_string(rows) + " texels came back " + std::to_string(tile.width) +
                               " x " + std::to_string(tile.height));
      for (int j = 0; j < rows; ++j)
        std::copy_n(texel_bytes(tile) + std::size_t(j) * cols * bytes, std::size_t(cols) * bytes,
                    texel_bytes(out) + (std::size_t(j0 + j) * ow + i0) * bytes);
    }
  return out;
}

}  // namespace

FloatRaster compute_by_windows(const TerrainWindows& t, const TexelRegion& region, const WindowMargins& m,
                               const WindowCompute& compute) {
  return by_windows<FloatRaster>(t, region, m, compute);
}

void convert_by_bands(const TerrainWindows& t, const std::function<RgbaImage(int row0, int rows)>& band,
                      const std::string& out_path, const PyramidOptions& options,
                      const std::function<void(double)>& progress, const std::string& what) {
  ImagePyramid::convert(
      t.width, t.height,
      [&](int y, int n, std::uint8_t* rgba) {
        const RgbaImage img = band(y, n);
        if (img.width != t.width || img.height != n)
          throw std::logic_error(what + ": a band of " + std::to_string(t.width) + " x " + std::to_string(n) +
                                 " texels came back " + std::to_string(img.width) + " x " +
                                 std::to_string(img.height));
        std::copy(img.rgba.begin(), img.rgba.end(), rgba);
      },
      out_path, options, progress, what);
}

WindowMargins shading_margins(const TerrainWindows& t, const ShadingOptions& o) {
  detail::validate_shading_options(o, t.transform, "shade_terrain");
  WindowMargins m{1, 1, 1, 1};  // Horn's 3 x 3
  if (o.method == ShadingMethod::RelativeHeight) {
    const int r = std::max(1, o.relative_radius);
    return {r, r, r, r};
  }
  if (!o.shadows || !(t.lo < t.hi)) return m;
  // A ray from the lowest sample is above the highest after climbing (hi - lo) ez: D metres of
  // horizontal travel toward the light; one sample more covers the crossing just beyond.
  pm::Heightfield frame_only;  // GridFrame's directions need only the transform
  frame_only.transform = t.transform;
  const detail::GridFrame f(frame_only, o.vertical_exaggeration);
  const double tan_h = std::tan(o.altitude_deg * std::numbers::pi / 180.0);
  const double D = (t.hi - t.lo) * o.vertical_exaggeration / tan_h;
  const std::vector<double> az = o.method == ShadingMethod::Multidirectional
                                     ? o.multidirectional_azimuths
                                     : std::vector<double>{o.azimuth_deg};
  const auto reach = [](double cells) { return int(std::min(std::ceil(std::abs(cells)), 1e9)) + 1; };
  for (double a : az) {
    const double ar = a * std::numbers::pi / 180.0;
    double uc, ur;
    f.grid_direction(std::sin(ar), std::cos(ar), uc, ur);
    int& mc = uc > 0 ? m.right : m.left;
    int& mr = ur > 0 ? m.bottom : m.top;
    mc = std::max(mc, reach(uc * D));
    mr = std::max(mr, reach(ur * D));
  }
  return m;
}

FloatRaster shade_terrain(const TerrainWindows& t, const ShadingOptions& o, const TexelRegion& region) {
  const WindowMargins m = shading_margins(t, o);
  return compute_by_windows(t, region, m,
                            [&](const pm::Heightfield& w, const TexelRegion& in, int c0, int r0) {
                              return detail::shade_window(w, o, in, {c0, r0, true, t.lo, t.hi});
                            });
}

FloatRaster terrain_attribute(const TerrainWindows& t, TerrainAttribute attribute,
                              const TexelRegion& region) {
  return compute_by_windows(t, region, {1, 1, 1, 1},
                            [&](const pm::Heightfield& w, const TexelRegion& in, int, int) {
                              return terrain_attribute(w, attribute, in);
                            });
}

void write_rule_pyramid(const TerrainWindows& t, TerrainAttribute attribute, const DesignRule& rule,
                        double sample_size_m, const std::string& out_path, const PyramidOptions& options,
                        const std::function<void(double)>& progress) {
  if (!(sample_size_m > 0.0)) throw std::invalid_argument(out_path + ": the sample size must be > 0 metres");
  const std::vector<LevelSize> sizes = pyramid_levels(t.width, t.height, options.max_texture_size);
  ImagePyramid::write_levels(
      t.width, t.height,
      [&](int k, int y, int n, std::uint8_t* rgba) {
        // Level k as render_pyramid_levels draws it: its w_k x h_k blocks of 2^k samples.
        const int s = 1 << k;
        const int cols = std::min(t.width, sizes[std::size_t(k)].width * s);
        const int rows = std::min(t.height, sizes[std::size_t(k)].height * s);
        const TexelRegion band{0, y * s, cols, std::min(rows - y * s, n * s), s};
        const RgbaImage img = by_windows<RgbaImage>(
            t, band, {1, 1, 1, 1}, [&](const pm::Heightfield& w, const TexelRegion& in, int, int) {
              return rule.render(terrain_attribute(w, attribute), in, sample_size_m);
            });
        std::copy(img.rgba.begin(), img.rgba.end(), rgba);
      },
      out_path, options, progress);
}

}  // namespace terralod::render
