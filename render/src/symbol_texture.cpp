// Symbol textures: map objects drawn as anti-aliased 2D symbols into the levels of a texture
// layer, each level showing the objects its view distance draws as symbols (symbol_texture.hpp).
#include "terralod/render/symbol_texture.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>

namespace terralod::render {

double symbol_level_distance_m(double texel_m) {
  assert(texel_m > 0);
  return texel_m * kSymbolReferenceFocalPx / std::sqrt(kSymbolReferenceGammaPx);
}

namespace {

// "src over dst" for straight-alpha RGBA8, src given as floats (colour 0..255, alpha 0..1).
void blend_over(std::uint8_t* dst, const double src_rgb[3], double src_a) {
  const double da = dst[3] / 255.0;
  const double oa = src_a + da * (1.0 - src_a);
  if (oa <= 0) return;
  for (int c = 0; c < 3; ++c)
    dst[c] = std::uint8_t(
        std::lround(std::clamp((src_rgb[c] * src_a + dst[c] * da * (1.0 - src_a)) / oa, 0.0, 255.0)));
  dst[3] = std::uint8_t(std::lround(std::clamp(oa * 255.0, 0.0, 255.0)));
}

}  // namespace

void draw_symbol(RgbaImage& image, double u, double v, const SymbolStyle& style, int row0) {
  assert(style.diameter_texels >= 1);
  const double r_out = 0.5 * style.diameter_texels;
  const double r_in = r_out - 1.0;  // the fill inside the 1-texel outline (none when <= 0)
  const int x0 = std::max(0, int(std::floor(u - r_out - 1))),
            x1 = std::min(image.width - 1, int(std::ceil(u + r_out + 1)));
  // Rows of the level, the image's row y being the level's row0 + y.
  const int y0 = std::max(row0, int(std::floor(v - r_out - 1))),
            y1 = std::min(row0 + image.height - 1, int(std::ceil(v + r_out + 1)));
  const double alpha = style.color[3] / 255.0;
  for (int y = y0; y <= y1; ++y)
    for (int x = x0; x <= x1; ++x) {
      const double r = std::hypot(x + 0.5 - u, y + 0.5 - v);
      const double outer = std::clamp(r_out + 0.5 - r, 0.0, 1.0);
      if (outer <= 0) continue;
      const double inner = r_in > 0 ? std::clamp(r_in + 0.5 - r, 0.0, 1.0) : 0.0;
      double rgb[3];
      for (int c = 0; c < 3; ++c)  // fill over `inner`, the dark outline over the rest
        rgb[c] = (inner * style.color[c] + (outer - inner) * 0.25 * style.color[c]) / outer;
      blend_over(image.pixel(x, y - row0), rgb, outer * alpha);
    }
}

std::vector<SymbolPosition> symbol_positions(std::span<const SymbolObject> objects, const GeoRect& georef,
                                             LevelSize size, double texel_m) {
  assert(size.width >= 1 && size.height >= 1 && texel_m > 0);
  assert(georef.width() > 0 && georef.height() > 0);
  const double d = symbol_level_distance_m(texel_m);
  std::vector<SymbolPosition> out;
  for (const SymbolObject& o : objects) {
    assert(o.rules != nullptr);
    if (o.rules->choose(d, o.extent_m * kSymbolReferenceFocalPx / d) != blocks::Representation::Symbol)
      continue;
    out.push_back({(o.anchor.x - georef.minx) / georef.width() * size.width,
                   (georef.maxy - o.anchor.y) / georef.height() * size.height});
  }
  return out;
}

RgbaImage render_symbol_rows(std::span<const SymbolPosition> positions, int width, int row0, int rows,
                             const SymbolStyle& style) {
  assert(width >= 1 && rows >= 1);
  RgbaImage img(width, rows);
  const double reach = 0.5 * style.diameter_texels + 1.0;  // as far as draw_symbol looks
  for (const SymbolPosition& p : positions)
    if (p.v + reach >= row0 - 1 && p.v - reach <= row0 + rows) draw_symbol(img, p.u, p.v, style, row0);
  return img;
}

RgbaImage render_symbol_level(std::span<const SymbolObject> objects, const GeoRect& georef, LevelSize size,
                              double texel_m, const SymbolStyle& style, std::size_t* drawn) {
  const std::vector<SymbolPosition> at = symbol_positions(objects, georef, size, texel_m);
  if (drawn) *drawn = at.size();
  return render_symbol_rows(at, size.width, 0, size.height, style);
}

}  // namespace terralod::render
