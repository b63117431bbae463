// FreeType glyph rasterisation with a dilated halo, shelf-packed into a two-channel atlas.
#include "glyph_atlas.hpp"

#include <algorithm>
#include <cassert>
#include <climits>
#include <cmath>
#include <stdexcept>

namespace terralod::render::detail {

GlyphAtlas::GlyphAtlas(const std::string& font_path, int halo_px) : fonts_(font_path), halo_(halo_px) {
  height_ = 64;
  texels_.assign(std::size_t(kWidth) * height_ * 2, 0);
}

void GlyphAtlas::place(Glyph& g, const std::vector<std::uint8_t>& two_channel) {
  if (g.width > kWidth)
    throw std::runtime_error(fonts_.face_file(0) + ": a glyph is wider than the label atlas");
  if (shelf_x_ + g.width > kWidth) shelf_y_ += shelf_h_, shelf_x_ = 0, shelf_h_ = 0;
  while (shelf_y_ + g.height > height_) {  // grow by doubling, keeping what is there
    height_ *= 2;
    texels_.resize(std::size_t(kWidth) * height_ * 2, 0);
  }
  g.atlas_x = shelf_x_, g.atlas_y = shelf_y_;
  for (int y = 0; y < g.height; ++y)
    std::copy_n(two_channel.begin() + std::ptrdiff_t(y) * g.width * 2, g.width * 2,
                texels_.begin() + (std::ptrdiff_t(g.atlas_y + y) * kWidth + g.atlas_x) * 2);
  shelf_x_ += g.width + 1;  // one empty texel between glyphs
  shelf_h_ = std::max(shelf_h_, g.height + 1);
  ++version_;
}

const GlyphAtlas::Glyph& GlyphAtlas::glyph(int face_index, std::uint32_t index, int size_px) {
  const auto key = std::make_tuple(face_index, size_px, index);
  if (auto it = glyphs_.find(key); it != glyphs_.end()) return it->second;
  const GlyphBitmap bm = fonts_.render(face_index, index, size_px);
  Glyph g;
  const int w = bm.width, h = bm.height, r = halo_;
  if (w > 0 && h > 0) {
    // Coverage padded by the halo radius, and the halo: the coverage's maximum over a disc of
    // radius r (a pixel whose centre is within r of an inked pixel's centre).
    g.width = w + 2 * r, g.height = h + 2 * r;
    g.left = bm.left - r, g.top = bm.top + r;
    std::vector<std::uint8_t> cov(std::size_t(g.width) * g.height, 0);
    for (int y = 0; y < h; ++y)
      std::copy_n(bm.coverage.begin() + std::ptrdiff_t(y) * w, w,
                  cov.begin() + std::ptrdiff_t(y + r) * g.width + r);
    std::vector<std::uint8_t> two(cov.size() * 2, 0);
    for (int y = 0; y < g.height; ++y)
      for (int x = 0; x < g.width; ++x) {
        std::uint8_t m = 0;
        for (int dy = -r; dy <= r; ++dy)
          for (int dx = -r; dx <= r; ++dx) {
            const int sx = x + dx, sy = y + dy;
            if (dx * dx + dy * dy > r * r || sx < 0 || sy < 0 || sx >= g.width || sy >= g.height) continue;
            m = std::max(m, cov[std::size_t(sy) * g.width + sx]);
          }
        two[2 * (std::size_t(y) * g.width + x)] = cov[std::size_t(y) * g.width + x];
        two[2 * (std::size_t(y) * g.width + x) + 1] = m;
      }
    place(g, two);
  }
  return glyphs_.emplace(key, g).first->second;
}

const LabelLayout& GlyphAtlas::layout(std::string_view text, int size_px) {
  assert(size_px >= 1 && "label size must be >= 1 pixel");
  std::string key = std::to_string(size_px);
  key.push_back('\0');
  key.append(text);
  if (const auto it = layouts_.find(key); it != layouts_.end()) return it->second;
  // Two generations: when the recent one is full it becomes the older one, and a layout found
  // there moves back, so what was laid out in the last kLayoutCache calls or so is found.
  LabelLayout l;
  if (auto it = older_layouts_.find(key); it != older_layouts_.end())
    l = std::move(it->second);
  else
    l = lay_out(text, size_px);
  if (layouts_.size() >= kLayoutCache) {
    older_layouts_.swap(layouts_);
    layouts_.clear();
  }
  return layouts_.emplace(std::move(key), std::move(l)).first->second;
}

LabelLayout GlyphAtlas::lay_out(std::string_view text, int size_px) {
  // Lines, and each one's glyphs and advance.
  std::vector<std::vector<char32_t>> lines(1);
  const std::vector<char32_t> cps = decode_utf8(text);
  for (std::size_t i = 0; i < cps.size(); ++i) {
    const char32_t c = cps[i];
    if (c == U'\n' || c == U'\r' || c == 0x2028) {
      if (c == U'\r' && i + 1 < cps.size() && cps[i + 1] == U'\n') ++i;
      lines.emplace_back();
    } else {
      lines.back().push_back(c);
    }
  }
  std::vector<ShapedLine> shaped;
  std::int64_t widest = 0;  // 26.6
  for (const auto& line : lines) {
    shaped.push_back(fonts_.shape(line, size_px));
    widest = std::max(widest, shaped.back().advance);
  }
  const int line_px = (fonts_.line_height(size_px) + 32) >> 6;

  LabelLayout out;
  int lo_x = INT_MAX, lo_y = INT_MAX, hi_x = INT_MIN, hi_y = INT_MIN;
  const int n_lines = int(shaped.size());
  for (int k = 0; k < n_lines; ++k) {
    const ShapedLine& line = shaped[std::size_t(k)];
    // Centred on the widest line; the last line's baseline is row 0.
    line.place((widest - line.advance) / 2, -(n_lines - 1 - k) * line_px,
               [&](const ShapedGlyph& sg, int origin_x, int origin_y) {
                 const Glyph& g = glyph(sg.face, sg.glyph, size_px);
                 if (g.width == 0) return;
                 PlacedGlyph p;
                 p.x0 = origin_x + g.left, p.y0 = origin_y - g.top;
                 p.x1 = p.x0 + g.width, p.y1 = p.y0 + g.height;
                 p.atlas_x = g.atlas_x, p.atlas_y = g.atlas_y;
                 lo_x = std::min(lo_x, p.x0), lo_y = std::min(lo_y, p.y0);
                 hi_x = std::max(hi_x, p.x1), hi_y = std::max(hi_y, p.y1);
                 out.glyphs.push_back(p);
               });
  }
  if (out.glyphs.empty()) return out;
  for (PlacedGlyph& p : out.glyphs) p.x0 -= lo_x, p.x1 -= lo_x, p.y0 -= lo_y, p.y1 -= lo_y;
  out.width = hi_x - lo_x, out.height = hi_y - lo_y;
  out.baseline_x = -lo_x, out.baseline_y = -lo_y;
  return out;
}

}  // namespace terralod::render::detail
