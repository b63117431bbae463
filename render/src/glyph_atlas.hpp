// GlyphAtlas: label glyphs rasterised by FreeType, each with a dilated halo, packed into one
// two-channel atlas image (coverage, halo), and the layout of a UTF-8 string from them. GL-free;
// ObjectRenderer uploads the atlas when it changes.
//
// Memory: 2 bytes per atlas texel (512 wide, rows grow by doubling) + about 40 bytes per glyph.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace terralod::render::detail {

/// One glyph of a laid-out label: its box in pixels relative to the label's top-left corner
/// (halo included, half-open) and where its texels start in the atlas.
struct PlacedGlyph {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  int atlas_x = 0, atlas_y = 0;
};

/// A label's glyphs and its rectangle: the union of the glyph boxes (ink + halo), whose
/// top-left corner is (0, 0); baseline_y is the baseline's row, baseline_x the pen's start.
struct LabelLayout {
  int width = 0, height = 0;
  int baseline_x = 0, baseline_y = 0;
  std::vector<PlacedGlyph> glyphs;
};

/// Unicode code points of UTF-8 text; an invalid or truncated sequence gives U+FFFD.
std::vector<char32_t> decode_utf8(std::string_view text);

class GlyphAtlas {
 public:
  static constexpr int kWidth = 512;

  /// Opens the font; std::runtime_error "<font>: ..." when FreeType cannot load it.
  GlyphAtlas(const std::string& font_path, int halo_px);
  ~GlyphAtlas();
  GlyphAtlas(const GlyphAtlas&) = delete;
  GlyphAtlas& operator=(const GlyphAtlas&) = delete;

  /// Lays `text` out at `size_px` (FreeType pixel size, the em height), rasterising glyphs not
  /// yet in the atlas. Glyph origins sit on whole pixels (pen rounded per glyph), so the boxes
  /// are exactly the pixels drawn. Text without ink gives a 0 x 0 layout.
  LabelLayout layout(std::string_view text, int size_px);

  int height() const { return height_; }
  /// kWidth x height() texels, 2 bytes each (coverage, halo), top row first.
  const std::vector<std::uint8_t>& texels() const { return texels_; }
  /// Bumped whenever texels() changes (new glyphs, growth).
  std::uint64_t version() const { return version_; }
  int halo_px() const { return halo_; }

 private:
  struct Glyph {
    int left = 0, top = 0, width = 0, height = 0;  // box relative to the pen on the baseline (y up)
    long advance = 0;                              // 26.6 pixels
    int atlas_x = 0, atlas_y = 0;
  };
  const Glyph& glyph(char32_t cp, int size_px);
  void place(Glyph& g, const std::vector<std::uint8_t>& two_channel);

  void* library_ = nullptr;  // FT_Library
  void* face_ = nullptr;     // FT_Face
  std::string font_;
  int halo_ = 0;
  int current_size_ = 0;
  std::map<std::pair<int, char32_t>, Glyph> glyphs_;
  std::vector<std::uint8_t> texels_;
  int height_ = 0;
  int shelf_x_ = 0, shelf_y_ = 0, shelf_h_ = 0;
  std::uint64_t version_ = 0;
};

}  // namespace terralod::render::detail
