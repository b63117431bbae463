// Loads the renderer's OpenGL entry points from a context (see gl_api.hpp for why), and the GL
// steps the renderers share: error checks, shader programs, the offscreen target.
#include "gl_api.hpp"

#include <cstdint>
#include <cstdio>

#include "terralod/render/gl_context.hpp"

namespace terralod::render::detail {

std::vector<std::string> GlApi::load(void* (*get_proc)(const char* name)) {
  std::vector<std::string> missing;
#define TERRALOD_GL_LOAD(type, name, required)         \
  name = reinterpret_cast<type>(get_proc("gl" #name)); \
  if (!name && required) missing.push_back("gl" #name);
  TERRALOD_GL_FUNCTIONS(TERRALOD_GL_LOAD)
#undef TERRALOD_GL_LOAD
  return missing;
}

void check_gl(const GlApi& gl, const char* what) {
  GLenum e = gl.GetError();
  if (e == GL_NO_ERROR) return;
  std::string codes;
  for (int n = 0; e != GL_NO_ERROR && n < 8; ++n, e = gl.GetError()) {
    char buf[16];
    std::snprintf(buf, sizeof buf, "%s0x%04x", codes.empty() ? "" : ", ", unsigned(e));
    codes += buf;
  }
  throw RenderError(std::string(what) + ": GL error " + codes);
}

namespace {

/// When `object`'s `status` (GL_COMPILE_STATUS of a shader, GL_LINK_STATUS of a program) is
/// false: deletes it and throws RenderError(failure + its info log + after).
void check_status(GLuint object, GLenum status, PFNGLGETSHADERIVPROC get_iv,
                  PFNGLGETSHADERINFOLOGPROC get_log, PFNGLDELETESHADERPROC destroy,
                  const std::string& failure, const std::string& after) {
  GLint ok = 0;
  get_iv(object, status, &ok);
  if (ok) return;
  char log[4096] = {};
  get_log(object, sizeof log, nullptr, log);
  destroy(object);
  throw RenderError(failure + log + after);
}

GLuint compile_shader(const GlApi& gl, GLenum type, const std::string& source, const std::string& who) {
  const GLuint s = gl.CreateShader(type);
  const char* text = source.c_str();
  gl.ShaderSource(s, 1, &text, nullptr);
  gl.CompileShader(s);
  const char* stage = type == GL_VERTEX_SHADER ? "vertex" : "fragment";
  check_status(s, GL_COMPILE_STATUS, gl.GetShaderiv, gl.GetShaderInfoLog, gl.DeleteShader,
               who + ": the " + stage + " shader does not compile: ", "\n" + source);
  return s;
}

}  // namespace

GLuint build_program(const GlApi& gl, const std::string& vertex, const std::string& fragment,
                     const std::string& who) {
  const GLuint vs = compile_shader(gl, GL_VERTEX_SHADER, vertex, who);
  GLuint fs = 0;
  try {
    fs = compile_shader(gl, GL_FRAGMENT_SHADER, fragment, who);
  } catch (...) {
    gl.DeleteShader(vs);
    throw;
  }
  const GLuint program = gl.CreateProgram();
  gl.AttachShader(program, vs);
  gl.AttachShader(program, fs);
  gl.LinkProgram(program);
  gl.DeleteShader(vs);
  gl.DeleteShader(fs);
  check_status(program, GL_LINK_STATUS, gl.GetProgramiv, gl.GetProgramInfoLog, gl.DeleteProgram,
               who + ": the shaders do not link: ", "");
  return program;
}

void OffscreenTarget::ensure(const GlApi& gl, int w, int h, const char* who) {
  if (fbo && w == width && h == height) return;
  if (!fbo) {
    gl.GenFramebuffers(1, &fbo);
    gl.GenRenderbuffers(1, &color_rb);
    gl.GenRenderbuffers(1, &depth_rb);
  }
  gl.BindRenderbuffer(GL_RENDERBUFFER, color_rb);
  gl.RenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, w, h);
  gl.BindRenderbuffer(GL_RENDERBUFFER, depth_rb);
  gl.RenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT32F, w, h);
  gl.BindFramebuffer(GL_FRAMEBUFFER, fbo);
  gl.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, color_rb);
  gl.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth_rb);
  const GLenum status = gl.CheckFramebufferStatus(GL_FRAMEBUFFER);
  if (status != GL_FRAMEBUFFER_COMPLETE)
    throw RenderError(std::string(who) + ": the " + std::to_string(w) + " x " + std::to_string(h) +
                      " framebuffer is incomplete (status " + std::to_string(status) + ")");
  check_gl(gl, (std::string(who) + ": allocating the framebuffer").c_str());
  width = w;
  height = h;
}

void OffscreenTarget::release(const GlApi& gl) {
  if (!fbo) return;
  gl.DeleteFramebuffers(1, &fbo);
  const GLuint rbs[2] = {color_rb, depth_rb};
  gl.DeleteRenderbuffers(2, rbs);
  fbo = color_rb = depth_rb = 0;
  width = height = 0;
}

Image OffscreenTarget::read_rgb(const GlApi& gl, const char* who) const {
  const int w = width, h = height;
  std::vector<std::uint8_t> rgba(std::size_t(w) * h * 4);
  gl.BindFramebuffer(GL_READ_FRAMEBUFFER, fbo);
  gl.ReadBuffer(GL_COLOR_ATTACHMENT0);
  gl.PixelStorei(GL_PACK_ALIGNMENT, 1);
  gl.ReadPixels(0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, rgba.data());
  check_gl(gl, (std::string(who) + ": reading the frame back").c_str());
  Image img;
  img.width = w;
  img.height = h;
  img.rgb.resize(std::size_t(w) * h * 3);
  for (int y = 0; y < h; ++y) {  // GL rows go bottom-up
    const std::uint8_t* src = rgba.data() + std::size_t(h - 1 - y) * w * 4;
    std::uint8_t* dst = img.pixel(0, y);
    for (int x = 0; x < w; ++x)
      dst[3 * x] = src[4 * x], dst[3 * x + 1] = src[4 * x + 1], dst[3 * x + 2] = src[4 * x + 2];
  }
  return img;
}

}  // namespace terralod::render::detail
