// Loads the renderer's OpenGL entry points from a context (see gl_api.hpp for why).
#include "gl_api.hpp"

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

}  // namespace terralod::render::detail
