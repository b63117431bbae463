// GlyphAtlas: label glyphs rasterised by FreeType, each with a dilated halo, packed into one
// two-channel atlas image (coverage, halo), and the layout of a UTF-8 string from them: shaped
// through the label font and its system fallbacks (font_chain.hpp: any script, right to left
// included), one line per '\n', lines centred. GL-free; ObjectRenderer uploads the atlas when it
// changes.
//
// Memory: 2 bytes per atlas texel (512 wide, rows grow by doubling) + about 40 bytes per glyph,
// and the layouts of the last 1 to 2 x kLayoutCache (text, size) pairs laid out, about 400 bytes
// each (labels are measured and drawn every frame; shaping them again each time would cost
// several microseconds a label).
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <tuple>
#include <unordered_map>
#include <vector>

#include "font_chain.hpp"

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

class GlyphAtlas {
 public:
  static constexpr int kWidth = 512;
  static constexpr std::size_t kLayoutCache = 16384;

  /// Opens the font; std::runtime_error "<font>: ..." when FreeType cannot load it.
  GlyphAtlas(const std::string& font_path, int halo_px);
  GlyphAtlas(const GlyphAtlas&) = delete;
  GlyphAtlas& operator=(const GlyphAtlas&) = delete;

  /// Lays `text` out at `size_px` (FreeType pixel size, the em height), rasterising glyphs not
  /// yet in the atlas. Glyph origins sit on whole pixels (pen rounded per glyph), so the boxes
  /// are exactly the pixels drawn. Lines break at '\n' ("\r\n", '\r', U+2028 too), each
  /// centred under the one before, the label font's line height apart; baseline_y is the last
  /// line's. Text without ink gives a 0 x 0 layout.
  const LabelLayout& layout(std::string_view text, int size_px);

  int height() const { return height_; }
  /// kWidth x height() texels, 2 bytes each (coverage, halo), top row first.
  const std::vector<std::uint8_t>& texels() const { return texels_; }
  /// Bumped whenever texels() changes (new glyphs, growth).
  std::uint64_t version() const { return version_; }
  int halo_px() const { return halo_; }

 private:
  struct Glyph {
    int left = 0, top = 0, width = 0, height = 0;  // box relative to the glyph's origin (y up)
    int atlas_x = 0, atlas_y = 0;
  };
  const Glyph& glyph(int face, std::uint32_t index, int size_px);
  void place(Glyph& g, const std::vector<std::uint8_t>& two_channel);
  LabelLayout lay_out(std::string_view text, int size_px);

  FontChain fonts_;
  int halo_ = 0;
  std::map<std::tuple<int, int, std::uint32_t>, Glyph> glyphs_;           // (face, size, glyph index)
  std::unordered_map<std::string, LabelLayout> layouts_, older_layouts_;  // key: size, '\0', text
  std::vector<std::uint8_t> texels_;
  int height_ = 0;
  int shelf_x_ = 0, shelf_y_ = 0, shelf_h_ = 0;
  std::uint64_t version_ = 0;
};

}  // namespace terralod::render::detail
