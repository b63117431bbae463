// The heads-up text overlay: text shaped and rasterised by the labels' font chain into an RGBA
// block, drawn as one alpha-blended textured quad over the default framebuffer.
#include "terralod/render/hud.hpp"

#include <algorithm>
#include <filesystem>
#include <map>
#include <stdexcept>
#include <utility>

#include "font_chain.hpp"
#include "gl_api.hpp"

namespace terralod::render {

struct TextRasterizer::Glyphs {
  std::map<std::pair<int, std::uint32_t>, detail::GlyphBitmap> drawn;  // (face, glyph) at the size
};

TextRasterizer::TextRasterizer(const HudOptions& options)
    : opt_(options), glyphs_(std::make_unique<Glyphs>()) {
  if (opt_.pixel_size < 6 || opt_.pixel_size > 128)
    throw std::invalid_argument("hud: pixel_size must be in [6, 128]");
  std::error_code ec;
  if (!std::filesystem::is_regular_file(opt_.font, ec))
    throw std::runtime_error(opt_.font + ": font file not found");
  fonts_ = std::make_unique<detail::FontChain>(opt_.font);
}

TextRasterizer::~TextRasterizer() = default;

TextImage TextRasterizer::rasterize(const std::vector<std::string>& lines) {
  const int px = opt_.pixel_size, line_h = px * 5 / 4, pad = px / 3;
  std::vector<detail::ShapedLine> shaped;
  std::int64_t widest = 64;  // 26.6: at least one pixel
  for (const std::string& l : lines) {
    shaped.push_back(fonts_->shape(detail::decode_utf8(l), px));
    widest = std::max(widest, shaped.back().advance);
  }
  TextImage t;
  t.width = int((widest + 63) >> 6) + 2 * pad;
  t.height = std::max(1, int(lines.size())) * line_h + 2 * pad;
  // The backing (black, 55 % opaque), and white text blended over it by its coverage (every
  // channel, alpha included, moves towards opaque white).
  t.rgba.resize(std::size_t(t.width) * t.height * 4);
  for (std::size_t p = 0; p < t.rgba.size(); p += 4)
    t.rgba[p] = t.rgba[p + 1] = t.rgba[p + 2] = 0, t.rgba[p + 3] = 140;
  for (std::size_t i = 0; i < shaped.size(); ++i)
    shaped[i].place(0, pad + int(i) * line_h + px, [&](const detail::ShapedGlyph& sg, int ox, int oy) {
      auto it = glyphs_->drawn.find({sg.face, sg.glyph});
      if (it == glyphs_->drawn.end())
        it = glyphs_->drawn.emplace(std::make_pair(sg.face, sg.glyph), fonts_->render(sg.face, sg.glyph, px))
                 .first;
      const detail::GlyphBitmap& bm = it->second;
      const int x0 = pad + ox + bm.left, y0 = oy - bm.top;
      for (int y = 0; y < bm.height; ++y)
        for (int x = 0; x < bm.width; ++x) {
          const int X = x0 + x, Y = y0 + y;
          const unsigned a = bm.coverage[std::size_t(y) * bm.width + x];
          if (a == 0 || X < 0 || Y < 0 || X >= t.width || Y >= t.height) continue;
          std::uint8_t* d = &t.rgba[(std::size_t(Y) * t.width + X) * 4];
          for (int c = 0; c < 4; ++c) d[c] = std::uint8_t((255 * a + d[c] * (255 - a) + 127) / 255);
        }
    });
  return t;
}

struct Hud::Gl {
  unsigned program = 0, vao = 0, texture = 0;
  int u_rect = -1, u_tex = -1;
};

namespace {

const char* kVertex = R"(#version 330 core
uniform vec4 rect;  // x0, y0, x1, y1 in normalised device coordinates
out vec2 uv;
void main() {
  vec2 c = vec2(gl_VertexID & 1, gl_VertexID >> 1);
  uv = vec2(c.x, 1.0 - c.y);
  gl_Position = vec4(mix(rect.xy, rect.zw, c), 0.0, 1.0);
}
)";
const char* kFragment = R"(#version 330 core
uniform sampler2D tex;
in vec2 uv;
out vec4 color;
void main() { color = texture(tex, uv); }
)";

}  // namespace

Hud::Hud(GlContext& context, const HudOptions& options)
    : ctx_(context), opt_(options), gl_(std::make_unique<Gl>()) {
  try {
    text_ = std::make_unique<TextRasterizer>(opt_);
    text_->rasterize({"terralod"});
  } catch (const std::exception& e) {
    font_error_ = e.what();
    return;
  }
  ctx_.make_current();
  const detail::GlApi& gl = ctx_.api();
  gl_->program = detail::build_program(gl, kVertex, kFragment, "hud");
  gl_->u_rect = gl.GetUniformLocation(gl_->program, "rect");
  gl_->u_tex = gl.GetUniformLocation(gl_->program, "tex");
  gl.GenVertexArrays(1, &gl_->vao);
  gl.GenTextures(1, &gl_->texture);
  gl.BindTexture(GL_TEXTURE_2D, gl_->texture);
  gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  detail::check_gl(gl, "hud: creating the overlay");
}

Hud::~Hud() {
  if (!gl_ || !gl_->program) return;
  ctx_.make_current();
  const detail::GlApi& gl = ctx_.api();
  gl.DeleteTextures(1, &gl_->texture);
  gl.DeleteVertexArrays(1, &gl_->vao);
  gl.DeleteProgram(gl_->program);
}

void Hud::set_lines(const std::vector<std::string>& lines) {
  if (lines == lines_) return;
  lines_ = lines;
  dirty_ = true;
}

void Hud::draw() {
  if (!has_font() || lines_.empty()) return;
  ctx_.make_current();
  const detail::GlApi& gl = ctx_.api();
  gl.BindFramebuffer(GL_FRAMEBUFFER, 0);
  gl.ActiveTexture(GL_TEXTURE0);
  gl.BindTexture(GL_TEXTURE_2D, gl_->texture);
  if (dirty_) {
    image_ = text_->rasterize(lines_);
    gl.PixelStorei(GL_UNPACK_ALIGNMENT, 1);
    gl.TexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, image_.width, image_.height, 0, GL_RGBA, GL_UNSIGNED_BYTE,
                  image_.rgba.data());
    dirty_ = false;
  }
  const int w = ctx_.framebuffer_width(), h = ctx_.framebuffer_height();
  gl.Viewport(0, 0, w, h);
  const float x0 = -1.0f + 2.0f * float(opt_.margin) / float(w);
  const float y1 = 1.0f - 2.0f * float(opt_.margin) / float(h);
  const float x1 = x0 + 2.0f * float(image_.width) / float(w);
  const float y0 = y1 - 2.0f * float(image_.height) / float(h);
  gl.Disable(GL_DEPTH_TEST);
  gl.Enable(GL_BLEND);
  gl.BlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
  gl.PolygonMode(GL_FRONT_AND_BACK, GL_FILL);
  gl.UseProgram(gl_->program);
  gl.Uniform4f(gl_->u_rect, x0, y0, x1, y1);
  gl.Uniform1i(gl_->u_tex, 0);
  gl.BindVertexArray(gl_->vao);
  gl.DrawArrays(GL_TRIANGLE_STRIP, 0, 4);
  gl.BindVertexArray(0);
  gl.Disable(GL_BLEND);
  gl.Enable(GL_DEPTH_TEST);
  detail::check_gl(gl, "hud: drawing the overlay");
}

}  // namespace terralod::render
