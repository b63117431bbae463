// The heads-up text overlay: OpenImageIO's render_text into an RGBA block, drawn as one
// alpha-blended textured quad over the default framebuffer.
#include "terralod/render/hud.hpp"

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>

#include <algorithm>
#include <filesystem>
#include <stdexcept>

#include "gl_api.hpp"

namespace terralod::render {

TextImage rasterize_text(const std::vector<std::string>& lines, const HudOptions& o) {
  if (o.pixel_size < 6 || o.pixel_size > 128)
    throw std::invalid_argument("hud: pixel_size must be in [6, 128]");
  std::error_code ec;
  if (!std::filesystem::is_regular_file(o.font, ec))
    throw std::runtime_error(o.font + ": font file not found");
  const int line_h = o.pixel_size * 5 / 4, pad = o.pixel_size / 3;
  int width = 1;
  for (const std::string& l : lines) {
    const OIIO::ROI r = OIIO::ImageBufAlgo::text_size(l, o.pixel_size, o.font);
    if (r.defined()) width = std::max(width, r.width());
  }
  TextImage t;
  t.width = width + 2 * pad;
  t.height = std::max(1, int(lines.size())) * line_h + 2 * pad;
  OIIO::ImageBuf buf(OIIO::ImageSpec(t.width, t.height, 4, OIIO::TypeDesc::UINT8));
  const float backing[4] = {0.0f, 0.0f, 0.0f, 0.55f};
  OIIO::ImageBufAlgo::fill(buf, backing);
  const float white[4] = {1.0f, 1.0f, 1.0f, 1.0f};
  for (std::size_t i = 0; i < lines.size(); ++i) {
    if (lines[i].empty()) continue;
    const int baseline = pad + int(i) * line_h + o.pixel_size;
    if (!OIIO::ImageBufAlgo::render_text(buf, pad, baseline, lines[i], o.pixel_size, o.font, white))
      throw std::runtime_error(o.font + ": cannot render text (" + buf.geterror() + ")");
  }
  t.rgba.resize(std::size_t(t.width) * t.height * 4);
  if (!buf.get_pixels(OIIO::ROI(0, t.width, 0, t.height, 0, 1, 0, 4), OIIO::TypeDesc::UINT8, t.rgba.data()))
    throw std::runtime_error("hud: cannot read the text image back (" + buf.geterror() + ")");
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
    rasterize_text({"terralod"}, opt_);
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
    image_ = rasterize_text(lines_, opt_);
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
