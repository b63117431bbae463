// FreeType glyph rasterisation with a dilated halo, shelf-packed into a two-channel atlas.
#include "glyph_atlas.hpp"

#include <ft2build.h>
#include FT_FREETYPE_H

#include <algorithm>
#include <cassert>
#include <climits>
#include <cmath>
#include <stdexcept>

namespace terralod::render::detail {

std::vector<char32_t> decode_utf8(std::string_view text) {
  std::vector<char32_t> out;
  std::size_t i = 0;
  const auto byte = [&](std::size_t k) { return static_cast<unsigned char>(text[k]); };
  while (i < text.size()) {
    const unsigned char c = byte(i);
    int extra = c < 0x80 ? 0 : (c >> 5) == 0x6 ? 1 : (c >> 4) == 0xE ? 2 : (c >> 3) == 0x1E ? 3 : -1;
    if (extra < 0) {
      out.push_back(0xFFFD), ++i;
      continue;
    }
    char32_t cp = extra == 0 ? c : (c & (0x3F >> extra));
    bool ok = true;
    for (int k = 1; ok && k <= extra; ++k) {
      if (i + k >= text.size() || (byte(i + k) & 0xC0) != 0x80) {
        ok = false;
        break;
      }
      cp = (cp << 6) | (byte(i + k) & 0x3F);
    }
    if (!ok || cp > 0x10FFFF) {
      out.push_back(0xFFFD), ++i;
      continue;
    }
    out.push_back(cp);
    i += std::size_t(extra) + 1;
  }
  return out;
}

GlyphAtlas::GlyphAtlas(const std::string& font_path, int halo_px) : font_(font_path), halo_(halo_px) {
  FT_Library lib = nullptr;
  if (FT_Init_FreeType(&lib) != 0) throw std::runtime_error(font_path + ": FreeType does not initialise");
  FT_Face face = nullptr;
  if (const FT_Error e = FT_New_Face(lib, font_path.c_str(), 0, &face); e != 0) {
    FT_Done_FreeType(lib);
    throw std::runtime_error(font_path + ": FreeType cannot load this font (error " + std::to_string(e) +
                             (e == FT_Err_Cannot_Open_Resource ? ": no such readable file" : "") + ")");
  }
  library_ = lib;
  face_ = face;
  height_ = 64;
  texels_.assign(std::size_t(kWidth) * height_ * 2, 0);
}

GlyphAtlas::~GlyphAtlas() {
  FT_Done_Face(static_cast<FT_Face>(face_));
  FT_Done_FreeType(static_cast<FT_Library>(library_));
}

void GlyphAtlas::place(Glyph& g, const std::vector<std::uint8_t>& two_channel) {
  if (g.width > kWidth) throw std::runtime_error(font_ + ": a glyph is wider than the label atlas");
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

const GlyphAtlas::Glyph& GlyphAtlas::glyph(char32_t cp, int size_px) {
  const auto key = std::make_pair(size_px, cp);
  if (auto it = glyphs_.find(key); it != glyphs_.end()) return it->second;
  FT_Face face = static_cast<FT_Face>(face_);
  if (current_size_ != size_px) {
    if (const FT_Error e = FT_Set_Pixel_Sizes(face, 0, FT_UInt(size_px)); e != 0)
      throw std::runtime_error(font_ + ": cannot set the pixel size " + std::to_string(size_px) + " (error " +
                               std::to_string(e) + ")");
    current_size_ = size_px;
  }
  if (const FT_Error e = FT_Load_Char(face, FT_ULong(cp), FT_LOAD_RENDER); e != 0)
    throw std::runtime_error(font_ + ": cannot render code point U+" + std::to_string(std::uint32_t(cp)) +
                             " (error " + std::to_string(e) + ")");
  const FT_GlyphSlot slot = face->glyph;
  const FT_Bitmap& bm = slot->bitmap;
  Glyph g;
  g.advance = slot->advance.x;
  const int w = int(bm.width), h = int(bm.rows), r = halo_;
  if (w > 0 && h > 0 && bm.pixel_mode == FT_PIXEL_MODE_GRAY) {
    // Coverage padded by the halo radius, and the halo: the coverage's maximum over a disc of
    // radius r (a pixel whose centre is within r of an inked pixel's centre).
    g.width = w + 2 * r, g.height = h + 2 * r;
    g.left = slot->bitmap_left - r, g.top = slot->bitmap_top + r;
    std::vector<std::uint8_t> cov(std::size_t(g.width) * g.height, 0);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        cov[std::size_t(y + r) * g.width + (x + r)] = bm.buffer[std::ptrdiff_t(y) * bm.pitch + x];
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

LabelLayout GlyphAtlas::layout(std::string_view text, int size_px) {
  assert(size_px >= 1 && "label size must be >= 1 pixel");
  LabelLayout out;
  long pen = 0;  // 26.6
  int lo_x = INT_MAX, lo_y = INT_MAX, hi_x = INT_MIN, hi_y = INT_MIN;
  for (const char32_t cp : decode_utf8(text)) {
    const Glyph& g = glyph(cp, size_px);
    const int origin = int((pen + 32) >> 6);
    pen += g.advance;
    if (g.width == 0) continue;
    PlacedGlyph p;
    p.x0 = origin + g.left, p.y0 = -g.top;  // y down from the baseline
    p.x1 = p.x0 + g.width, p.y1 = p.y0 + g.height;
    p.atlas_x = g.atlas_x, p.atlas_y = g.atlas_y;
    lo_x = std::min(lo_x, p.x0), lo_y = std::min(lo_y, p.y0);
    hi_x = std::max(hi_x, p.x1), hi_y = std::max(hi_y, p.y1);
    out.glyphs.push_back(p);
  }
  if (out.glyphs.empty()) return out;
  for (PlacedGlyph& p : out.glyphs) p.x0 -= lo_x, p.x1 -= lo_x, p.y0 -= lo_y, p.y1 -= lo_y;
  out.width = hi_x - lo_x, out.height = hi_y - lo_y;
  out.baseline_x = -lo_x, out.baseline_y = -lo_y;
  return out;
}

}  // namespace terralod::render::detail
