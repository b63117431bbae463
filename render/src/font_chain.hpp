// FontChain: a label font and the system fonts that stand in for the characters it lacks, and the
// shaping of one line of text through them into positioned glyphs, in visual order.
//
//   - Fallback: a character the font has no glyph for is looked up through fontconfig, once per
//     character, among the system's scalable, non-colour fonts (the first of fontconfig's sorted
//     sans-serif list whose character set has it); its face is opened once and kept. Combining
//     marks and format characters (joiners, variation selectors) stay in the face of the
//     character before them, so a cluster is shaped in one face. Characters no font has are
//     drawn as the label font's missing-glyph box.
//   - Bidi: the line's embedding levels come from FriBidi (the Unicode bidirectional algorithm,
//     base direction from the first strong character), so Arabic and Hebrew read right to left
//     and numbers or Latin words inside them stay left to right.
//   - Shaping: each run of one face, one level and one script is shaped by HarfBuzz with the whole
//     line as context (Arabic joining across a face change, Indic reordering and conjuncts,
//     ligatures, kerning); runs are placed in visual order (rule L2).
//
// GL-free and not thread-safe (one chain per renderer). Memory: the FreeType faces (the label
// font's and each fallback's, opened once) and one entry per distinct character looked up.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace terralod::render::detail {

/// Unicode code points of UTF-8 text; an invalid or truncated sequence gives U+FFFD.
std::vector<char32_t> decode_utf8(std::string_view text);

/// One glyph of a shaped line: which face of the chain, its glyph index there (0 = the face's
/// missing glyph), and where it goes, in 26.6 pixels: the pen moves by x_advance after it and
/// the glyph's origin is the pen plus (x_offset, -y_offset) (y up in HarfBuzz, down on screen).
struct ShapedGlyph {
  int face = 0;
  std::uint32_t glyph = 0;
  std::int32_t x_advance = 0, x_offset = 0, y_offset = 0;
};

/// A glyph's coverage (0..255, top row first) and its box relative to the glyph's origin on the
/// baseline: `left` pixels right of it, `top` pixels above it. Empty for a glyph without ink.
struct GlyphBitmap {
  int left = 0, top = 0, width = 0, height = 0;
  std::vector<std::uint8_t> coverage;
};

/// A shaped line: its glyphs, left to right, and its width.
struct ShapedLine {
  std::vector<ShapedGlyph> glyphs;
  std::int64_t advance = 0;  ///< 26.6 pixels: the glyphs' x_advance summed

  /// Calls f(glyph, x, y) for each glyph with its origin on whole pixels (y down), the pen
  /// starting at `pen` (26.6 pixels) on the pixel row `baseline`: the one placement of the
  /// labels and the HUD.
  template <class F>
  void place(std::int64_t pen, int baseline, F&& f) const {
    for (const ShapedGlyph& g : glyphs) {
      f(g, int((pen + g.x_offset + 32) >> 6), baseline - int((std::int64_t(g.y_offset) + 32) >> 6));
      pen += g.x_advance;
    }
  }
};

class FontChain {
 public:
  /// Opens the label font; std::runtime_error "<font>: ..." when FreeType cannot load it.
  explicit FontChain(const std::string& font_path);
  ~FontChain();
  FontChain(const FontChain&) = delete;
  FontChain& operator=(const FontChain&) = delete;

  /// The glyphs of one line of text (code points; control characters count as spaces) at
  /// `size_px` pixels an em, left to right on screen.
  ShapedLine shape(const std::vector<char32_t>& line, int size_px);

  /// Rasterises glyph `glyph` of face index `face` at `size_px` (hinted, as shape() measures);
  /// std::runtime_error naming the font file when FreeType cannot.
  GlyphBitmap render(int face, std::uint32_t glyph, int size_px);
  /// The file of face index `face` (0 is the label font), for error messages and tests.
  const std::string& face_file(int face) const;
  /// The line height of the label font at `size_px` (26.6 pixels: ascender - descender + gap).
  std::int32_t line_height(int size_px);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace terralod::render::detail
