// Label text (render/src/font_chain.hpp, glyph_atlas.hpp): place names in any script get real
// glyphs from the system's fonts (fonts-noto-core, fonts-wqy-zenhei: scripts/install-deps.sh),
// shaped (Arabic joining, Indic reordering, kerning), right-to-left scripts in visual order, and
// multi-line labels centred line under line. GL-free.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "font_chain.hpp"
#include "glyph_atlas.hpp"
#include "terralod/render/hud.hpp"

namespace {

using terralod::render::detail::decode_utf8;
using terralod::render::detail::FontChain;
using terralod::render::detail::GlyphAtlas;
using terralod::render::detail::LabelLayout;
using terralod::render::detail::ShapedGlyph;

const std::string kFont = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";
constexpr int kSize = 20;

std::vector<ShapedGlyph> shape(FontChain& fonts, const std::string& utf8) {
  return fonts.shape(decode_utf8(utf8), kSize).glyphs;
}

/// The glyph indices of a shaped line, left to right.
std::vector<std::uint32_t> glyphs(const std::vector<ShapedGlyph>& s) {
  std::vector<std::uint32_t> out;
  for (const ShapedGlyph& g : s) out.push_back(g.glyph);
  return out;
}

/// The glyph of one character shaped alone.
std::uint32_t alone(FontChain& fonts, const std::string& utf8) {
  const auto s = shape(fonts, utf8);
  EXPECT_EQ(s.size(), 1u) << utf8;
  return s.empty() ? 0 : s[0].glyph;
}

TEST(LabelText, EveryScriptGetsRealGlyphsFromTheSystemsFonts) {
  // Before the fallback fonts, every non-Latin, non-Greek, non-Cyrillic, non-Arabic, non-Hebrew
  // character was drawn as DejaVu Sans's missing-glyph box (glyph 0).
  FontChain fonts(kFont);
  for (const std::string name : {"東京", "北京市", "서울", "القاهرة", "תל אביב", "नई दिल्ली", "กรุงเทพ",
                                 "Αθήνα", "Москва", "ዐዲስ አበባ", "Zürich", "Kraków"}) {
    const auto s = shape(fonts, name);
    ASSERT_FALSE(s.empty()) << name;
    for (const ShapedGlyph& g : s)
      EXPECT_NE(g.glyph, 0u) << name << ": a glyph is the missing-glyph box of " << fonts.face_file(g.face);
  }
  // Latin text stays in the label font.
  for (const ShapedGlyph& g : shape(fonts, "Mont Blanc")) EXPECT_EQ(g.face, 0);
  EXPECT_NE(shape(fonts, "東京")[0].face, 0);
}

TEST(LabelText, ACharacterNoFontHasIsTheLabelFontsMissingGlyph) {
  FontChain fonts(kFont);
  const auto s = shape(fonts, "a\U0010FFFDb");  // a private-use character of plane 16
  ASSERT_EQ(s.size(), 3u);
  EXPECT_EQ(s[1].face, 0);
  EXPECT_EQ(s[1].glyph, 0u);
  EXPECT_GT(s[1].x_advance, 0);  // the box takes its room
}

TEST(LabelText, TheFallbackOfACharacterDoesNotDependOnWhatCameBefore) {
  FontChain a(kFont), b(kFont);
  const auto a1 = shape(a, "中"), a2 = shape(a, "ก");
  const auto b2 = shape(b, "ก"), b1 = shape(b, "中");
  EXPECT_EQ(a.face_file(a1[0].face), b.face_file(b1[0].face));
  EXPECT_EQ(a.face_file(a2[0].face), b.face_file(b2[0].face));
  EXPECT_EQ(a1[0].glyph, b1[0].glyph);
}

TEST(LabelText, ArabicLettersJoin) {
  FontChain fonts(kFont);
  // بيت: beh, yeh, teh, joined on both sides but the ends: initial, medial and final forms, none
  // of them the letter's isolated glyph.
  const auto joined = glyphs(shape(fonts, "بيت"));
  const std::vector<std::uint32_t> isolated = {alone(fonts, "ب"), alone(fonts, "ي"), alone(fonts, "ت")};
  ASSERT_FALSE(joined.empty());
  int same = 0;
  for (std::uint32_t g : joined) same += std::count(isolated.begin(), isolated.end(), g) > 0;
  EXPECT_EQ(same, 0) << "an Arabic letter kept its isolated form inside a word";
}

TEST(LabelText, RightToLeftTextReadsRightToLeftAndNumbersInsideItLeftToRight) {
  FontChain fonts(kFont);
  const std::uint32_t alef = alone(fonts, "א"), bet = alone(fonts, "ב"), one = alone(fonts, "1"),
                      two = alone(fonts, "2"), space = alone(fonts, " "), a = alone(fonts, "a"),
                      b = alone(fonts, "b");
  // Hebrew first: a right-to-left line; "12" stays left to right within it.
  EXPECT_EQ(glyphs(shape(fonts, "אב 12")), (std::vector<std::uint32_t>{one, two, space, bet, alef}));
  // Latin first: a left-to-right line with a Hebrew word in it.
  EXPECT_EQ(glyphs(shape(fonts, "ab אב")), (std::vector<std::uint32_t>{a, b, space, bet, alef}));
  // Brackets are mirrored in right-to-left text: "(א)" shows ")" where the line starts on the right.
  const auto bracketed = glyphs(shape(fonts, "א(ב)"));
  ASSERT_EQ(bracketed.size(), 4u);
  EXPECT_EQ(bracketed[0], alone(fonts, "("));  // the closing bracket, mirrored, on the left
  EXPECT_EQ(bracketed[1], bet);
  EXPECT_EQ(bracketed[2], alone(fonts, ")"));
  EXPECT_EQ(bracketed[3], alef);
}

TEST(LabelText, ADevanagariVowelSignIsDrawnBeforeItsConsonant) {
  FontChain fonts(kFont);
  // कि: ka + vowel sign i (U+093F), which is written to the left of the consonant it follows.
  const auto s = shape(fonts, "कि");
  const std::uint32_t ka = alone(fonts, "क");
  ASSERT_EQ(s.size(), 2u);
  EXPECT_NE(s[0].glyph, ka);
  EXPECT_EQ(s[1].glyph, ka);
}

TEST(LabelText, CombiningMarksStayInTheFaceOfTheirBase) {
  FontChain fonts(kFont);
  const auto jp = shape(fonts, "か\u3099");  // hiragana ka + combining voiced sound mark
  for (const ShapedGlyph& g : jp) EXPECT_EQ(g.face, jp[0].face);
  const auto latin = shape(fonts, "e\u0301");  // e + combining acute: composed to é by the font
  for (const ShapedGlyph& g : latin) EXPECT_EQ(g.face, 0);
}

TEST(LabelText, KerningTightensPairsTheFontKerns) {
  FontChain fonts(kFont);
  const auto av = shape(fonts, "AV");
  ASSERT_EQ(av.size(), 2u);
  const std::int32_t apart = shape(fonts, "A")[0].x_advance + shape(fonts, "V")[0].x_advance;
  EXPECT_LT(av[0].x_advance + av[1].x_advance, apart);
}

TEST(LabelText, LinesAreCentredUnderOneAnotherAndTheLastLineSitsOnTheBaseline) {
  GlyphAtlas atlas(kFont, 2);
  const LabelLayout top = atlas.layout("Mont Blanc", kSize);
  const LabelLayout bottom = atlas.layout("4808 m", kSize);
  const LabelLayout both = atlas.layout("Mont Blanc\n4808 m", kSize);
  ASSERT_GT(bottom.width, 0);
  ASSERT_LT(bottom.width, top.width);
  EXPECT_EQ(both.width, top.width);
  // Below the baseline: the last line's descent; above it: one line height more than the top
  // line's ascent.
  EXPECT_EQ(both.height - both.baseline_y, bottom.height - bottom.baseline_y);
  EXPECT_GT(both.height, top.height + bottom.height - 2 * 2);
  EXPECT_EQ(both.glyphs.size(), top.glyphs.size() + bottom.glyphs.size());
  for (const std::string crlf : {"Mont Blanc\r\n4808 m", "Mont Blanc\r4808 m", "Mont Blanc\u20284808 m"}) {
    const LabelLayout l = atlas.layout(crlf, kSize);
    EXPECT_EQ(l.width, both.width) << crlf;
    EXPECT_EQ(l.height, both.height) << crlf;
  }
  // The second line is centred: its glyphs' box is centred on the first's, within a pixel.
  int lo = both.width, hi = 0;
  for (const auto& g : both.glyphs)
    if (g.y0 > both.baseline_y - bottom.baseline_y - 1) lo = std::min(lo, g.x0), hi = std::max(hi, g.x1);
  EXPECT_LE(std::abs((lo + hi) - both.width), 2);
}

TEST(LabelText, LayoutsAreCachedAndTheSameAfterTheCacheIsCleared) {
  GlyphAtlas atlas(kFont, 2);
  const LabelLayout first = atlas.layout("東京 Tōkyō", kSize);
  for (std::size_t i = 0; i < 2 * GlyphAtlas::kLayoutCache + 10; ++i) atlas.layout(std::to_string(i), kSize);
  const LabelLayout again = atlas.layout("東京 Tōkyō", kSize);
  ASSERT_EQ(first.glyphs.size(), again.glyphs.size());
  EXPECT_EQ(first.width, again.width);
  EXPECT_EQ(first.height, again.height);
  for (std::size_t i = 0; i < first.glyphs.size(); ++i) {
    EXPECT_EQ(first.glyphs[i].x0, again.glyphs[i].x0);
    EXPECT_EQ(first.glyphs[i].atlas_x, again.glyphs[i].atlas_x);
    EXPECT_EQ(first.glyphs[i].atlas_y, again.glyphs[i].atlas_y);
  }
}

TEST(HudText, APickedNameInAnyScriptIsDrawnWithItsOwnGlyphs) {
  // The HUD shows a picked object's name: with the label font alone (DejaVu Sans Mono), 東 and 京
  // were the same missing-glyph box.
  terralod::render::TextRasterizer hud;
  const auto east = hud.rasterize({"東"}), capital = hud.rasterize({"京"}),
             none = hud.rasterize({"\U0010FFFD"});
  ASSERT_EQ(east.width, capital.width);
  ASSERT_EQ(east.height, capital.height);
  EXPECT_NE(east.rgba, capital.rgba);
  EXPECT_NE(east.rgba, none.rgba);
  // White ink on the 55 % black backing; lines are as wide as the longest.
  const auto one = hud.rasterize({"a"}), two = hud.rasterize({"a", "abc"});
  EXPECT_GT(two.width, one.width);
  EXPECT_GT(two.height, one.height);
  EXPECT_EQ(one.rgba[3], 140);
  EXPECT_EQ(*std::max_element(one.rgba.begin(), one.rgba.end()), 255);
  EXPECT_THROW(terralod::render::TextRasterizer({.font = "/nonexistent.ttf"}), std::runtime_error);
}

}  // namespace
