// The back-end independent part of a GL context: loading entry points and reading GlInfo.
#include "terralod/render/gl_context.hpp"

#include <cstdio>
#include <string>

#include "gl_api.hpp"

namespace terralod::render {

GlContext::GlContext() = default;
GlContext::~GlContext() = default;

void GlContext::load(void* (*get_proc)(const char* name), const std::string& backend) {
  auto api = std::make_unique<detail::GlApi>();
  const std::vector<std::string> missing = api->load(get_proc);
  if (!missing.empty()) {
    std::string list;
    for (const std::string& m : missing) list += (list.empty() ? "" : ", ") + m;
    throw RenderError(backend + ": the GL context lacks required entry points: " + list);
  }
  auto str = [&](GLenum name) {
    const GLubyte* s = api->GetString(name);
    return s ? std::string(reinterpret_cast<const char*>(s)) : std::string();
  };
  GlInfo info;
  info.backend = backend;
  info.vendor = str(GL_VENDOR);
  info.renderer = str(GL_RENDERER);
  info.version = str(GL_VERSION);
  info.glsl_version = str(GL_SHADING_LANGUAGE_VERSION);
  api->GetIntegerv(GL_MAJOR_VERSION, &info.major);
  api->GetIntegerv(GL_MINOR_VERSION, &info.minor);
  api->GetError();  // GL_MAJOR_VERSION is unknown to GL < 3.0: the check below reports it
  if (info.major * 10 + info.minor < 33)
    throw RenderError(backend + ": OpenGL 3.3 or newer is needed, the context is '" + info.version + "' (" +
                      info.renderer + ")");
  GLint mask = 0;
  api->GetIntegerv(GL_CONTEXT_PROFILE_MASK, &mask);
  info.core_profile = (mask & GL_CONTEXT_CORE_PROFILE_BIT) != 0;
  bool arb_clip_control = false;
  GLint extensions = 0;
  api->GetIntegerv(GL_NUM_EXTENSIONS, &extensions);
  for (GLint i = 0; i < extensions; ++i) {
    const GLubyte* e = api->GetStringi(GL_EXTENSIONS, GLuint(i));
    if (e && std::string(reinterpret_cast<const char*>(e)) == "GL_ARB_clip_control") arb_clip_control = true;
  }
  // glXGetProcAddress returns a stub for any name, so availability comes from the version.
  info.clip_control = api->ClipControl && (info.major * 10 + info.minor >= 45 || arb_clip_control);
  if (!info.clip_control) api->ClipControl = nullptr;
  detail::check_gl(*api, (backend + ": reading the context's description").c_str());
  api_ = std::move(api);
  info_ = std::move(info);
}

}  // namespace terralod::render
