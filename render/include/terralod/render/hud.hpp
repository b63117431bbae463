// Hud: a heads-up text overlay (frame rate, tolerance, triangles, ...) drawn over a window
// after the terrain, and the GL-free text rasteriser behind it.
//
// Usage:
//   terralod::render::Hud hud(*window);                    // a WindowContext (or any context)
//   hud.set_lines({"fps 60.0", "tau 1.00 px"});            // re-rasterised only when it changes
//   renderer.present(/*swap=*/false);  hud.draw();  window->swap_buffers();
//
// Contract:
//   - Text is rasterised on the CPU by FreeType with a TrueType font: HudOptions::font, by
//     default DejaVu Sans Mono (Debian package fonts-dejavu-core), and the system's fonts for
//     the characters it lacks, shaped as the 3D labels are (any script, right-to-left ones in
//     visual order: render/src/font_chain.hpp), so a picked object's name reads as its label.
//     When the font cannot be loaded, has_font() is false, draw() draws nothing and
//     font_error() says why; nothing throws for a missing font (the demo still flies).
//   - TextRasterizer is GL-free: white text with a translucent dark backing, RGBA8, top row
//     first, width = longest line, one line every `pixel_size * 1.25` pixels.
//   - draw() renders one textured, alpha-blended quad at the top-left corner of the context's
//     default framebuffer (in pixels, not scaled with the window), restoring the blend and
//     depth state it changes. GL failures throw RenderError.
//   - Memory: 4 bytes per pixel of the text block, on the CPU and on the GPU.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "terralod/render/gl_context.hpp"

namespace terralod::render {

namespace detail {
class FontChain;
}

struct HudOptions {
  std::string font = "/usr/share/fonts/truetype/dejavu/DejaVuSansMono.ttf";
  int pixel_size = 16;  ///< font size, pixels, 6..128
  int margin = 8;       ///< distance from the window's top-left corner, pixels
};

/// RGBA8 text block, top row first.
struct TextImage {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgba;
};

/// Rasterises lines of UTF-8 text (GL-free). Keeps the fonts open and the glyphs it drew; not
/// thread-safe.
class TextRasterizer {
 public:
  /// std::invalid_argument for a pixel size outside [6, 128]; std::runtime_error naming the
  /// font when it cannot be loaded.
  explicit TextRasterizer(const HudOptions& options = {});
  ~TextRasterizer();
  TextRasterizer(const TextRasterizer&) = delete;
  TextRasterizer& operator=(const TextRasterizer&) = delete;

  TextImage rasterize(const std::vector<std::string>& lines);

 private:
  struct Glyphs;
  HudOptions opt_;
  std::unique_ptr<detail::FontChain> fonts_;
  std::unique_ptr<Glyphs> glyphs_;
};

class Hud {
 public:
  explicit Hud(GlContext& context, const HudOptions& options = {});
  ~Hud();
  Hud(const Hud&) = delete;
  Hud& operator=(const Hud&) = delete;

  void set_lines(const std::vector<std::string>& lines);
  void draw();
  bool has_font() const { return font_error_.empty(); }
  const std::string& font_error() const { return font_error_; }

 private:
  struct Gl;
  GlContext& ctx_;
  HudOptions opt_;
  std::unique_ptr<Gl> gl_;
  std::unique_ptr<TextRasterizer> text_;
  std::vector<std::string> lines_;
  TextImage image_;
  bool dirty_ = false;
  std::string font_error_;
};

}  // namespace terralod::render
