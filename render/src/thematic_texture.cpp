// Thematic textures: colour mappers (class tables, ramps, bands), DEM attributes (elevation,
// slope, aspect) and LOD-dependent design rules (Döllner & Baumann, dynamic 3D maps, sec. 5.1).
// GL-free. Memory: the output image plus at most one reduced float raster per call.
#include "terralod/render/thematic_texture.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

#include "shading_common.hpp"

namespace terralod::render {

ClassTable::ClassTable(std::map<int, Rgba> classes, Rgba unknown)
    : classes_(std::move(classes)), unknown_(unknown) {}

Rgba ClassTable::map(float value) const {
  if (std::isnan(value)) return nodata;
  const float r = std::round(value);
  if (std::abs(value - r) > 1e-3f || std::abs(r) > 2e9f)
    throw std::invalid_argument("class raster: value " + std::to_string(value) +
                                " is not an integral class id");
  const auto it = classes_.find(static_cast<int>(r));
  return it == classes_.end() ? unknown_ : it->second;
}

ColorRamp::ColorRamp(std::vector<Stop> stops, Mode mode) : stops_(std::move(stops)), mode_(mode) {
  if (stops_.empty()) throw std::invalid_argument("colour ramp: no stops");
  for (std::size_t k = 0; k < stops_.size(); ++k) {
    if (!std::isfinite(stops_[k].value))
      throw std::invalid_argument("colour ramp: stop " + std::to_string(k) + " is not finite");
    if (k > 0 && !(stops_[k].value > stops_[k - 1].value))
      throw std::invalid_argument("colour ramp: stop values must increase strictly (stop " +
                                  std::to_string(k) + " = " + std::to_string(stops_[k].value) + ")");
  }
}

Rgba ColorRamp::map(float v) const {
  if (std::isnan(v)) return nodata;
  // First stop with value > v.
  const auto it =
      std::upper_bound(stops_.begin(), stops_.end(), v, [](float x, const Stop& s) { return x < s.value; });
  if (mode_ == Mode::Step) {
    if (it == stops_.begin()) return nodata;
    return std::prev(it)->color;
  }
  if (it == stops_.begin()) return stops_.front().color;
  if (it == stops_.end()) return stops_.back().color;
  const Stop& a = *std::prev(it);
  const Stop& b = *it;
  const double t = (double(v) - a.value) / (double(b.value) - a.value);
  Rgba c;
  for (int ch = 0; ch < 4; ++ch)
    c[ch] = static_cast<std::uint8_t>(std::lround(a.color[ch] + t * (double(b.color[ch]) - a.color[ch])));
  return c;
}

RgbaImage apply_mapper(const FloatRaster& values, const ColorMapper& mapper) {
  RgbaImage out(values.width, values.height);
  for (std::size_t i = 0; i < values.v.size(); ++i) {
    const Rgba c = mapper.map(values.v[i]);
    std::copy(c.begin(), c.end(), out.rgba.begin() + std::ptrdiff_t(4 * i));
  }
  return out;
}

FloatRaster terrain_attribute(const pm::Heightfield& hf, TerrainAttribute attribute,
                              const TexelRegion& region) {
  if (hf.width() < 1 || hf.height() < 1) throw std::invalid_argument("terrain_attribute: empty heightfield");
  region.check(hf.width(), hf.height(), "terrain_attribute");
  const double det = hf.transform.determinant();
  if (!(std::abs(det) > 0.0)) throw std::invalid_argument("terrain_attribute: grid transform is singular");
  const int ow = region.out_width(hf.width()), oh = region.out_height(hf.height());
  FloatRaster out(ow, oh);
  const detail::GridFrame f(hf, 1.0);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int j = 0; j < oh; ++j)
    for (int i = 0; i < ow; ++i) {
      const int c = region.col0 + i * region.step, r = region.row0 + j * region.step;
      float& dst = out.at(i, j);
      if (!hf.valid(c, r)) {
        dst = nan;
        continue;
      }
      if (attribute == TerrainAttribute::Elevation) {
        dst = static_cast<float>(hf.at(c, r));
        continue;
      }
      double gx, gy;
      f.gradient(c, r, gx, gy);
      const double g = std::hypot(gx, gy);
      if (attribute == TerrainAttribute::SlopeDegrees) {
        dst = static_cast<float>(std::atan(g) * 180.0 / std::numbers::pi);
      } else if (g == 0.0) {
        dst = nan;  // flat: no aspect
      } else {
        // Downhill direction (-gx, -gy) as an azimuth clockwise from north.
        double a = std::atan2(-gx, -gy) * 180.0 / std::numbers::pi;
        if (a < 0.0) a += 360.0;
        if (a >= 360.0) a -= 360.0;
        dst = static_cast<float>(a);
      }
    }
  return out;
}

FloatRaster reduce_raster(const FloatRaster& values, const TexelRegion& region, Reduction reduction) {
  region.check(values.width, values.height, "reduce_raster");
  const int ow = region.out_width(values.width), oh = region.out_height(values.height);
  const int c_end = region.col0 + region.cols_in(values.width),
            r_end = region.row0 + region.rows_in(values.height);
  FloatRaster out(ow, oh);
  std::vector<float> block;
  for (int j = 0; j < oh; ++j)
    for (int i = 0; i < ow; ++i) {
      const int c0 = region.col0 + i * region.step, r0 = region.row0 + j * region.step;
      if (reduction == Reduction::Nearest || region.step == 1) {
        out.at(i, j) = values.at(c0, r0);
        continue;
      }
      block.clear();
      for (int r = r0; r < std::min(r0 + region.step, r_end); ++r)
        for (int c = c0; c < std::min(c0 + region.step, c_end); ++c)
          if (!std::isnan(values.at(c, r))) block.push_back(values.at(c, r));
      if (block.empty()) {
        out.at(i, j) = std::numeric_limits<float>::quiet_NaN();
      } else if (reduction == Reduction::Mean) {
        double s = 0.0;
        for (float v : block) s += v;
        out.at(i, j) = static_cast<float>(s / double(block.size()));
      } else {  // Majority: most frequent rounded class id, smallest on ties
        for (float& v : block) v = std::round(v);
        std::sort(block.begin(), block.end());
        float best = block[0];
        std::size_t best_n = 0;
        for (std::size_t k = 0; k < block.size();) {
          std::size_t e = k;
          while (e < block.size() && block[e] == block[k]) ++e;
          if (e - k > best_n) best_n = e - k, best = block[k];
          k = e;
        }
        out.at(i, j) = best;
      }
    }
  return out;
}

void LodDesignRule::add(double max_texel_size_m, std::shared_ptr<const ColorMapper> mapper) {
  assert(max_texel_size_m > 0.0 && mapper);
  entries_.emplace_back(max_texel_size_m, std::move(mapper));
}

const ColorMapper& LodDesignRule::mapper_for(double texel_size_m) const {
  assert(!entries_.empty());
  for (const auto& [limit, m] : entries_)
    if (texel_size_m <= limit) return *m;
  return *entries_.back().second;
}

RgbaImage LodDesignRule::render(const FloatRaster& values, const TexelRegion& region,
                                double sample_size_m) const {
  assert(sample_size_m > 0.0);
  const ColorMapper& m = mapper_for(region.step * sample_size_m);
  return apply_mapper(reduce_raster(values, region, generalise_), m);
}

std::vector<RgbaImage> render_pyramid_levels(const DesignRule& rule, const FloatRaster& values,
                                             double sample_size_m, int max_texture_size) {
  assert(values.width >= 1 && values.height >= 1 && sample_size_m > 0.0 && max_texture_size >= 1);
  std::vector<RgbaImage> out;
  const std::vector<LevelSize> sizes = pyramid_levels(values.width, values.height, max_texture_size);
  for (std::size_t k = 0; k < sizes.size(); ++k) {
    const int step = 1 << k;
    // w_k = max(1, floor(W / 2^k)), so w_k 2^k <= W unless w_k is the 1 of max(1, .); then the
    // whole width is one block. Either way ceil(cols / step) = w_k.
    const TexelRegion region{0, 0, std::min(values.width, sizes[k].width * step),
                             std::min(values.height, sizes[k].height * step), step};
    out.push_back(rule.render(values, region, sample_size_m));
    if (out.back().width != sizes[k].width || out.back().height != sizes[k].height)
      throw std::invalid_argument("render_pyramid_levels: the rule drew level " + std::to_string(k) + " as " +
                                  std::to_string(out.back().width) + " x " +
                                  std::to_string(out.back().height) + " texels instead of " +
                                  std::to_string(sizes[k].width) + " x " + std::to_string(sizes[k].height));
  }
  return out;
}

}  // namespace terralod::render
