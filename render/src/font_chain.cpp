// The label font, its fontconfig fallbacks, and the bidi + HarfBuzz shaping of a line of text.
#include "font_chain.hpp"

#include <fontconfig/fontconfig.h>
#include <fribidi.h>
#include <ft2build.h>
#include FT_FREETYPE_H
#include <hb-ft.h>
#include <hb.h>

#include <algorithm>
#include <map>
#include <stdexcept>
#include <unordered_map>
#include <utility>

namespace terralod::render::detail {

namespace {

struct Face {
  std::string file;
  FT_Face ft = nullptr;
  hb_font_t* hb = nullptr;
  int size_px = 0;
};

/// A character that belongs to the cluster of the one before it: combining marks, format
/// characters (joiners, bidi marks) and variation selectors (which are marks).
bool joins_previous(hb_unicode_general_category_t gc) {
  return gc == HB_UNICODE_GENERAL_CATEGORY_NON_SPACING_MARK ||
         gc == HB_UNICODE_GENERAL_CATEGORY_SPACING_MARK || gc == HB_UNICODE_GENERAL_CATEGORY_ENCLOSING_MARK ||
         gc == HB_UNICODE_GENERAL_CATEGORY_FORMAT;
}

bool neutral_script(hb_script_t s) {
  return s == HB_SCRIPT_COMMON || s == HB_SCRIPT_INHERITED || s == HB_SCRIPT_UNKNOWN;
}

}  // namespace

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

struct FontChain::Impl {
  FT_Library library = nullptr;
  std::vector<Face> faces;                          // [0]: the label font
  std::map<std::pair<std::string, int>, int> open;  // (file, face index in file) -> faces index
  std::unordered_map<char32_t, int> face_of;        // characters the label font lacks -> face
  FcFontSet* fallbacks = nullptr;                   // sans-serif fonts in fontconfig's order
  FcConfig* config = nullptr;
  bool fallbacks_listed = false;
  hb_buffer_t* buffer = nullptr;

  ~Impl() {
    if (buffer) hb_buffer_destroy(buffer);
    for (Face& f : faces) {
      if (f.hb) hb_font_destroy(f.hb);  // releases its reference to the FT_Face's user data only
      if (f.ft) FT_Done_Face(f.ft);
    }
    if (fallbacks) FcFontSetDestroy(fallbacks);
    if (config) FcConfigDestroy(config);
    if (library) FT_Done_FreeType(library);
  }

  /// Opens `file` (its face `index`) once; -1 when FreeType cannot.
  int open_face(const std::string& file, int index) {
    if (const auto it = open.find({file, index}); it != open.end()) return it->second;
    FT_Face ft = nullptr;
    if (FT_New_Face(library, file.c_str(), index, &ft) != 0) return open[{file, index}] = -1;
    return add_face(file, index, ft);
  }

  int add_face(const std::string& file, int index, FT_Face ft) {
    Face f;
    f.file = file;
    f.ft = ft;
    f.hb = hb_ft_font_create(ft, nullptr);
    // Hinted metrics, as the glyphs are rasterised (GlyphAtlas): advances on whole pixels.
    hb_ft_font_set_load_flags(f.hb, FT_LOAD_DEFAULT);
    faces.push_back(f);
    return open[{file, index}] = int(faces.size()) - 1;
  }

  void set_size(Face& f, int size_px) {
    if (f.size_px == size_px) return;
    if (const FT_Error e = FT_Set_Pixel_Sizes(f.ft, 0, FT_UInt(size_px)); e != 0)
      throw std::runtime_error(f.file + ": cannot set the pixel size " + std::to_string(size_px) +
                               " (error " + std::to_string(e) + ")");
    hb_ft_font_changed(f.hb);
    f.size_px = size_px;
  }

  /// fontconfig's sans-serif fonts, best first, listed once: every character the label font
  /// lacks is looked up in the same order, so its face does not depend on which labels came
  /// first. Without fontconfig's configuration the list is empty (missing-glyph boxes).
  void list_fallbacks() {
    fallbacks_listed = true;
    config = FcInitLoadConfigAndFonts();
    if (!config) return;
    FcPattern* pattern = FcNameParse(reinterpret_cast<const FcChar8*>("sans-serif"));
    if (!pattern) return;
    FcConfigSubstitute(config, pattern, FcMatchPattern);
    FcDefaultSubstitute(pattern);
    FcResult result = FcResultNoMatch;
    fallbacks = FcFontSort(config, pattern, FcFalse, nullptr, &result);
    FcPatternDestroy(pattern);
  }

  /// The face that draws `cp`: the label font when it has the character, else the first
  /// scalable, non-colour fallback that has it, else the label font (its missing glyph).
  int face_for(char32_t cp) {
    if (FT_Get_Char_Index(faces[0].ft, cp) != 0) return 0;
    if (const auto it = face_of.find(cp); it != face_of.end()) return it->second;
    if (!fallbacks_listed) list_fallbacks();
    int chosen = 0;
    for (int i = 0; fallbacks && i < fallbacks->nfont && chosen == 0; ++i) {
      FcPattern* font = fallbacks->fonts[i];
      FcCharSet* chars = nullptr;
      FcBool scalable = FcFalse, color = FcFalse;
      FcChar8* file = nullptr;
      int index = 0;
      if (FcPatternGetCharSet(font, FC_CHARSET, 0, &chars) != FcResultMatch || !FcCharSetHasChar(chars, cp))
        continue;
      if (FcPatternGetBool(font, FC_SCALABLE, 0, &scalable) != FcResultMatch || !scalable) continue;
      if (FcPatternGetBool(font, FC_COLOR, 0, &color) == FcResultMatch && color) continue;
      if (FcPatternGetString(font, FC_FILE, 0, &file) != FcResultMatch) continue;
      FcPatternGetInteger(font, FC_INDEX, 0, &index);
      const int f = open_face(reinterpret_cast<const char*>(file), index);
      if (f > 0 && FT_Get_Char_Index(faces[std::size_t(f)].ft, cp) != 0) chosen = f;
    }
    face_of.emplace(cp, chosen);
    return chosen;
  }
};

FontChain::FontChain(const std::string& font_path) : impl_(std::make_unique<Impl>()) {
  if (FT_Init_FreeType(&impl_->library) != 0)
    throw std::runtime_error(font_path + ": FreeType does not initialise");
  FT_Face face = nullptr;
  if (const FT_Error e = FT_New_Face(impl_->library, font_path.c_str(), 0, &face); e != 0)
    throw std::runtime_error(font_path + ": FreeType cannot load this font (error " + std::to_string(e) +
                             (e == FT_Err_Cannot_Open_Resource ? ": no such readable file" : "") + ")");
  impl_->add_face(font_path, 0, face);
  impl_->buffer = hb_buffer_create();
  if (!hb_buffer_allocation_successful(impl_->buffer)) throw std::bad_alloc();
}

FontChain::~FontChain() = default;

GlyphBitmap FontChain::render(int face, std::uint32_t glyph, int size_px) {
  Face& f = impl_->faces.at(std::size_t(face));
  impl_->set_size(f, size_px);
  if (const FT_Error e = FT_Load_Glyph(f.ft, FT_UInt(glyph), FT_LOAD_DEFAULT | FT_LOAD_RENDER); e != 0)
    throw std::runtime_error(f.file + ": cannot render glyph " + std::to_string(glyph) + " (error " +
                             std::to_string(e) + ")");
  const FT_GlyphSlot slot = f.ft->glyph;
  const FT_Bitmap& bm = slot->bitmap;
  GlyphBitmap out;
  if (bm.width == 0 || bm.rows == 0 || bm.pixel_mode != FT_PIXEL_MODE_GRAY) return out;
  out.left = slot->bitmap_left, out.top = slot->bitmap_top;
  out.width = int(bm.width), out.height = int(bm.rows);
  out.coverage.resize(std::size_t(out.width) * std::size_t(out.height));
  for (int y = 0; y < out.height; ++y)
    std::copy_n(bm.buffer + std::ptrdiff_t(y) * bm.pitch, out.width,
                out.coverage.begin() + std::ptrdiff_t(y) * out.width);
  return out;
}

const std::string& FontChain::face_file(int face) const { return impl_->faces.at(std::size_t(face)).file; }

std::int32_t FontChain::line_height(int size_px) {
  Face& f = impl_->faces[0];
  impl_->set_size(f, size_px);
  return std::int32_t(f.ft->size->metrics.height);
}

ShapedLine FontChain::shape(const std::vector<char32_t>& line, int size_px) {
  const std::size_t n = line.size();
  ShapedLine out;
  if (n == 0) return out;
  hb_unicode_funcs_t* ucd = hb_unicode_funcs_get_default();
  std::vector<std::uint32_t> text(line.begin(), line.end());
  for (std::uint32_t& c : text)
    if (c < 0x20 || (c >= 0x7F && c < 0xA0)) c = 0x20;  // a tab or stray control draws as a space

  // Embedding levels (UAX #9), the paragraph's direction from its first strong character.
  std::vector<FriBidiCharType> types(n);
  std::vector<FriBidiBracketType> brackets(n);
  std::vector<FriBidiLevel> levels(n, 0);
  fribidi_get_bidi_types(text.data(), FriBidiStrIndex(n), types.data());
  fribidi_get_bracket_types(text.data(), FriBidiStrIndex(n), types.data(), brackets.data());
  FriBidiParType direction = FRIBIDI_PAR_ON;
  if (!fribidi_get_par_embedding_levels_ex(types.data(), brackets.data(), FriBidiStrIndex(n), &direction,
                                           levels.data()))
    std::fill(levels.begin(), levels.end(), FriBidiLevel(0));

  // Face and script of each character: marks and format characters join the one before them;
  // characters of no particular script (spaces, digits, punctuation) take their neighbours'.
  std::vector<int> face(n);
  std::vector<hb_script_t> script(n);
  for (std::size_t i = 0; i < n; ++i) {
    const auto gc = hb_unicode_general_category(ucd, text[i]);
    const bool joins = i > 0 && joins_previous(gc);
    face[i] = joins && (gc == HB_UNICODE_GENERAL_CATEGORY_FORMAT ||
                        FT_Get_Char_Index(impl_->faces[std::size_t(face[i - 1])].ft, text[i]) != 0)
                  ? face[i - 1]
                  : impl_->face_for(text[i]);
    script[i] = hb_unicode_script(ucd, text[i]);
  }
  hb_script_t last = HB_SCRIPT_COMMON;
  for (std::size_t i = 0; i < n; ++i)
    if (neutral_script(script[i]))
      script[i] = last;
    else
      last = script[i];
  last = HB_SCRIPT_COMMON;
  for (std::size_t i = n; i-- > 0;)  // leading neutrals take the first script after them
    if (neutral_script(script[i]))
      script[i] = last;
    else
      last = script[i];

  // Runs of one face, level and script, in logical order.
  struct Run {
    std::size_t start, length;
    FriBidiLevel level;
  };
  std::vector<Run> runs;
  for (std::size_t i = 0; i < n; ++i)
    if (i == 0 || face[i] != face[i - 1] || levels[i] != levels[i - 1] || script[i] != script[i - 1])
      runs.push_back({i, 1, levels[i]});
    else
      ++runs.back().length;

  // Visual order (rule L2): from the highest level down to the lowest odd one, reverse every
  // sequence of runs at that level or higher.
  FriBidiLevel highest = 0, lowest_odd = 255;
  for (const Run& r : runs) {
    highest = std::max(highest, r.level);
    if (r.level % 2) lowest_odd = std::min(lowest_odd, r.level);
  }
  for (int level = highest; level >= int(lowest_odd) && level > 0; --level)
    for (std::size_t i = 0; i < runs.size();) {
      if (runs[i].level < level) {
        ++i;
        continue;
      }
      std::size_t j = i;
      while (j < runs.size() && runs[j].level >= level) ++j;
      std::reverse(runs.begin() + std::ptrdiff_t(i), runs.begin() + std::ptrdiff_t(j));
      i = j;
    }

  // Each run shaped with the whole line as context; HarfBuzz gives a right-to-left run's glyphs
  // in visual order already.
  hb_buffer_t* buf = impl_->buffer;
  for (const Run& r : runs) {
    Face& f = impl_->faces[std::size_t(face[r.start])];
    impl_->set_size(f, size_px);
    hb_buffer_clear_contents(buf);
    hb_buffer_add_utf32(buf, text.data(), int(n), unsigned(r.start), int(r.length));
    hb_buffer_set_direction(buf, r.level % 2 ? HB_DIRECTION_RTL : HB_DIRECTION_LTR);
    hb_buffer_set_script(buf, script[r.start]);
    hb_buffer_set_language(buf, hb_language_get_default());
    hb_shape(f.hb, buf, nullptr, 0);
    unsigned count = 0;
    const hb_glyph_info_t* info = hb_buffer_get_glyph_infos(buf, &count);
    const hb_glyph_position_t* pos = hb_buffer_get_glyph_positions(buf, &count);
    for (unsigned k = 0; k < count; ++k) {
      out.glyphs.push_back(
          {face[r.start], info[k].codepoint, pos[k].x_advance, pos[k].x_offset, pos[k].y_offset});
      out.advance += pos[k].x_advance;
    }
  }
  return out;
}

}  // namespace terralod::render::detail
