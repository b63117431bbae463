// The CPU reference of texture-layer combination (dynamic-3d-maps-texture-layers.txt
// section 6): blend, add, subtract, multiply, masks, lens, key-frame sequences.
// Memory: the output image only.
#include "terralod/render/texture_layers.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>

namespace terralod::render {
namespace {

float clamp01(float v) { return std::min(1.0f, std::max(0.0f, v)); }

// Nearest texel of an image covering `g` at world point (x, y); nullptr outside.
const std::uint8_t* nearest(const RgbaImage& img, const GeoRect& g, double x, double y) {
  const double u = (x - g.minx) / g.width(), v = (g.maxy - y) / g.height();
  if (u < 0 || u >= 1 || v < 0 || v >= 1) return nullptr;
  const int px = std::min(img.width - 1, int(u * img.width));
  const int py = std::min(img.height - 1, int(v * img.height));
  return img.pixel(px, py);
}

}  // namespace

SequencePosition sequence_position(int frames, float time) {
  assert(frames >= 1 && time >= 0.0f && time <= float(frames - 1));
  SequencePosition p;
  p.i = std::min(frames - 1, int(std::floor(time)));
  p.j = std::min(frames - 1, p.i + 1);
  p.f = p.j == p.i ? 0.0f : time - float(p.i);
  return p;
}

bool decal_mode(std::span<const LayerStyle> styles) {
  return std::any_of(styles.begin(), styles.end(),
                     [](const LayerStyle& s) { return s.enabled && s.topographic; });
}

std::array<float, 3> combine_texels(std::span<const LayerStyle> styles,
                                    std::span<const std::array<float, 4>> texels, float lens_alpha,
                                    float light, const LayerStackOptions& o) {
  assert(styles.size() == texels.size());
  std::array<float, 3> c = o.base_color;
  for (std::size_t i = 0; i < styles.size(); ++i) {
    const LayerStyle& s = styles[i];
    if (!s.enabled || s.mask_only) continue;
    assert(s.weight >= 0.0f && s.weight <= 1.0f);
    float m = 1.0f;
    if (s.mask == MaskSource::Layer) {
      assert(s.mask_layer >= 0 && std::size_t(s.mask_layer) < styles.size() &&
             std::size_t(s.mask_layer) != i);
      m = texels[std::size_t(s.mask_layer)][3];
    } else if (s.mask == MaskSource::Lens) {
      m = lens_alpha;
    }
    if (s.mask != MaskSource::None && s.invert_mask) m = 1.0f - m;
    const std::array<float, 4>& t = texels[i];
    const float w = s.weight * t[3] * m;
    for (int k = 0; k < 3; ++k) {
      switch (s.op) {
        case LayerOp::Blend:
          c[k] = c[k] + (t[k] - c[k]) * w;
          break;
        case LayerOp::Add:
          c[k] = c[k] + w * t[k];
          break;
        case LayerOp::Subtract:
          c[k] = c[k] - w * t[k];
          break;
        case LayerOp::Multiply:
          c[k] = c[k] * (1.0f + (t[k] - 1.0f) * w);
          break;
      }
      c[k] = clamp01(c[k]);
    }
  }
  if (o.lighting && !decal_mode(styles))
    for (float& v : c) v = clamp01(v * light);
  return c;
}

RgbaImage combine_layers(std::span<const LayerStyle> styles, std::span<const LayerSource> sources,
                         const RgbaImage* lens_image, const Lens& lens, const GeoRect& out, int width,
                         int height, const LayerStackOptions& options) {
  assert(styles.size() == sources.size() && width >= 1 && height >= 1);
  assert(!lens.enabled || lens_image);
  RgbaImage img(width, height);
  std::vector<std::array<float, 4>> texels(styles.size());
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const double wx = out.minx + (x + 0.5) * out.width() / width;
      const double wy = out.maxy - (y + 0.5) * out.height() / height;
      for (std::size_t i = 0; i < styles.size(); ++i) {
        const LayerSource& src = sources[i];
        assert(!src.frames.empty());
        const SequencePosition sp = sequence_position(int(src.frames.size()), styles[i].time);
        const std::uint8_t* a = nearest(src.frames[std::size_t(sp.i)], src.georef, wx, wy);
        const std::uint8_t* b = nearest(src.frames[std::size_t(sp.j)], src.georef, wx, wy);
        for (int k = 0; k < 4; ++k) {
          const float ka = a ? a[k] / 255.0f : 0.0f, kb = b ? b[k] / 255.0f : 0.0f;
          texels[i][std::size_t(k)] = (1.0f - sp.f) * ka + sp.f * kb;
        }
      }
      float lens_alpha = 0.0f;
      if (lens.enabled)
        if (const std::uint8_t* p = nearest(*lens_image, lens.rect, wx, wy)) lens_alpha = p[3] / 255.0f;
      const std::array<float, 3> c = combine_texels(styles, texels, lens_alpha, 1.0f, options);
      std::uint8_t* d = img.pixel(x, y);
      for (int k = 0; k < 3; ++k) d[k] = std::uint8_t(std::lround(c[std::size_t(k)] * 255.0f));
      d[3] = 255;
    }
  return img;
}

RgbaImage make_lens_texture(int size, float soft) {
  assert(size >= 1 && soft >= 0.0f && soft <= 1.0f);
  RgbaImage img(size, size);
  const float r = size / 2.0f;
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x) {
      const float d = std::hypot(x + 0.5f - r, y + 0.5f - r) / r;  // 0 centre, 1 at the circle
      const float a = soft > 0.0f ? clamp01((1.0f - d) / soft) : (d <= 1.0f ? 1.0f : 0.0f);
      img.set(x, y, {255, 255, 255, std::uint8_t(std::lround(a * 255.0f))});
    }
  return img;
}

}  // namespace terralod::render
