// The table of OpenGL entry points terralod's renderer uses, loaded from the current context,
// and the few GL steps every renderer shares: error checks, shader programs, the offscreen target.
//
// Why a loader of our own: libOSMesa and GLVND's libGL both export gl* symbols, and a process
// that links both resolves them to whichever comes first. Loading every entry point through
// the context's own GetProcAddress sidesteps that, and keeps libGL (and X11) out of offscreen
// processes. The list is short (about 60 functions of GL 3.3 core plus glClipControl).
//
// Only renderer sources include this file: it pulls in <GL/glcorearb.h> (types and enums only,
// no prototypes since GL_GLEXT_PROTOTYPES is not defined), which must not meet <GL/gl.h>.
#pragma once

#include <GL/glcorearb.h>

#include <string>
#include <vector>

#include "terralod/render/image.hpp"

namespace terralod::render::detail {

// X(type, name, required): the member is `name`, the GL symbol "gl" #name.
// clang-format off
#define TERRALOD_GL_FUNCTIONS(X)                                         \
  X(PFNGLGETSTRINGPROC, GetString, true)                                 \
  X(PFNGLGETSTRINGIPROC, GetStringi, true)                               \
  X(PFNGLGETINTEGERVPROC, GetIntegerv, true)                             \
  X(PFNGLGETERRORPROC, GetError, true)                                   \
  X(PFNGLVIEWPORTPROC, Viewport, true)                                   \
  X(PFNGLCLEARCOLORPROC, ClearColor, true)                               \
  X(PFNGLCLEARDEPTHPROC, ClearDepth, true)                               \
  X(PFNGLCLEARPROC, Clear, true)                                         \
  X(PFNGLENABLEPROC, Enable, true)                                       \
  X(PFNGLDISABLEPROC, Disable, true)                                     \
  X(PFNGLDEPTHFUNCPROC, DepthFunc, true)                                 \
  X(PFNGLDEPTHMASKPROC, DepthMask, true)                                 \
  X(PFNGLPOLYGONMODEPROC, PolygonMode, true)                             \
  X(PFNGLPOLYGONOFFSETPROC, PolygonOffset, true)                         \
  X(PFNGLREADPIXELSPROC, ReadPixels, true)                               \
  X(PFNGLREADBUFFERPROC, ReadBuffer, true)                               \
  X(PFNGLDRAWBUFFERPROC, DrawBuffer, true)                               \
  X(PFNGLPIXELSTOREIPROC, PixelStorei, true)                             \
  X(PFNGLFINISHPROC, Finish, true)                                       \
  X(PFNGLDRAWELEMENTSPROC, DrawElements, true)                           \
  X(PFNGLGENBUFFERSPROC, GenBuffers, true)                               \
  X(PFNGLDELETEBUFFERSPROC, DeleteBuffers, true)                         \
  X(PFNGLBINDBUFFERPROC, BindBuffer, true)                               \
  X(PFNGLBUFFERDATAPROC, BufferData, true)                               \
  X(PFNGLBUFFERSUBDATAPROC, BufferSubData, true)                         \
  X(PFNGLGENVERTEXARRAYSPROC, GenVertexArrays, true)                     \
  X(PFNGLDELETEVERTEXARRAYSPROC, DeleteVertexArrays, true)               \
  X(PFNGLBINDVERTEXARRAYPROC, BindVertexArray, true)                     \
  X(PFNGLENABLEVERTEXATTRIBARRAYPROC, EnableVertexAttribArray, true)     \
  X(PFNGLVERTEXATTRIBPOINTERPROC, VertexAttribPointer, true)             \
  X(PFNGLCREATESHADERPROC, CreateShader, true)                           \
  X(PFNGLSHADERSOURCEPROC, ShaderSource, true)                           \
  X(PFNGLCOMPILESHADERPROC, CompileShader, true)                         \
  X(PFNGLGETSHADERIVPROC, GetShaderiv, true)                             \
  X(PFNGLGETSHADERINFOLOGPROC, GetShaderInfoLog, true)                   \
  X(PFNGLDELETESHADERPROC, DeleteShader, true)                           \
  X(PFNGLCREATEPROGRAMPROC, CreateProgram, true)                         \
  X(PFNGLATTACHSHADERPROC, AttachShader, true)                           \
  X(PFNGLLINKPROGRAMPROC, LinkProgram, true)                             \
  X(PFNGLGETPROGRAMIVPROC, GetProgramiv, true)                           \
  X(PFNGLGETPROGRAMINFOLOGPROC, GetProgramInfoLog, true)                 \
  X(PFNGLDELETEPROGRAMPROC, DeleteProgram, true)                         \
  X(PFNGLUSEPROGRAMPROC, UseProgram, true)                               \
  X(PFNGLGETUNIFORMLOCATIONPROC, GetUniformLocation, true)               \
  X(PFNGLUNIFORM1FPROC, Uniform1f, true)                                 \
  X(PFNGLUNIFORM2FPROC, Uniform2f, true)                                 \
  X(PFNGLUNIFORM3FPROC, Uniform3f, true)                                 \
  X(PFNGLUNIFORMMATRIX4FVPROC, UniformMatrix4fv, true)                   \
  X(PFNGLGENFRAMEBUFFERSPROC, GenFramebuffers, true)                     \
  X(PFNGLDELETEFRAMEBUFFERSPROC, DeleteFramebuffers, true)               \
  X(PFNGLBINDFRAMEBUFFERPROC, BindFramebuffer, true)                     \
  X(PFNGLFRAMEBUFFERRENDERBUFFERPROC, FramebufferRenderbuffer, true)     \
  X(PFNGLCHECKFRAMEBUFFERSTATUSPROC, CheckFramebufferStatus, true)       \
  X(PFNGLGENRENDERBUFFERSPROC, GenRenderbuffers, true)                   \
  X(PFNGLDELETERENDERBUFFERSPROC, DeleteRenderbuffers, true)             \
  X(PFNGLBINDRENDERBUFFERPROC, BindRenderbuffer, true)                   \
  X(PFNGLRENDERBUFFERSTORAGEPROC, RenderbufferStorage, true)             \
  X(PFNGLBLITFRAMEBUFFERPROC, BlitFramebuffer, true)                     \
  X(PFNGLDRAWARRAYSPROC, DrawArrays, true)                               \
  X(PFNGLGENTEXTURESPROC, GenTextures, true)                             \
  X(PFNGLDELETETEXTURESPROC, DeleteTextures, true)                       \
  X(PFNGLBINDTEXTUREPROC, BindTexture, true)                             \
  X(PFNGLACTIVETEXTUREPROC, ActiveTexture, true)                         \
  X(PFNGLTEXIMAGE2DPROC, TexImage2D, true)                               \
  X(PFNGLTEXSUBIMAGE2DPROC, TexSubImage2D, true)                         \
  X(PFNGLTEXPARAMETERIPROC, TexParameteri, true)                         \
  X(PFNGLGENERATEMIPMAPPROC, GenerateMipmap, true)                       \
  X(PFNGLGETTEXIMAGEPROC, GetTexImage, true)                             \
  X(PFNGLFRAMEBUFFERTEXTURE2DPROC, FramebufferTexture2D, true)           \
  X(PFNGLUNIFORM1IPROC, Uniform1i, true)                                 \
  X(PFNGLUNIFORM1FVPROC, Uniform1fv, true)                               \
  X(PFNGLUNIFORM1IVPROC, Uniform1iv, true)                               \
  X(PFNGLUNIFORM4FPROC, Uniform4f, true)                                 \
  X(PFNGLBLENDFUNCPROC, BlendFunc, true)                                 \
  X(PFNGLBLENDEQUATIONPROC, BlendEquation, true)                         \
  X(PFNGLVERTEXATTRIBDIVISORPROC, VertexAttribDivisor, true)             \
  X(PFNGLDRAWARRAYSINSTANCEDPROC, DrawArraysInstanced, true)             \
  X(PFNGLCLIPCONTROLPROC, ClipControl, false)
// clang-format on

struct GlApi {
#define TERRALOD_GL_MEMBER(type, name, required) type name = nullptr;
  TERRALOD_GL_FUNCTIONS(TERRALOD_GL_MEMBER)
#undef TERRALOD_GL_MEMBER

  /// Loads every entry point with `get_proc`; returns the names of required ones it missed.
  std::vector<std::string> load(void* (*get_proc)(const char* name));
};

/// Throws RenderError("<what>: GL error 0x0502 ...") when glGetError reports errors.
void check_gl(const GlApi& gl, const char* what);

/// Compiles GLSL `vertex` and `fragment` source and links them into a program (the shader
/// objects are deleted; the program is the caller's). On failure nothing stays allocated and
/// RenderError says "<who>: the vertex|fragment shader does not compile: <log>" followed by the
/// source, or "<who>: the shaders do not link: <log>".
GLuint build_program(const GlApi& gl, const std::string& vertex, const std::string& fragment,
                     const std::string& who);

/// The offscreen framebuffer both renderers draw into: RGBA8 colour and 32-bit float depth
/// renderbuffers, reallocated when the size changes. `who` names the renderer in errors.
struct OffscreenTarget {
  GLuint fbo = 0, color_rb = 0, depth_rb = 0;
  int width = 0, height = 0;
  /// Makes the target w x h (a no-op when it already is); RenderError when incomplete.
  void ensure(const GlApi& gl, int w, int h, const char* who);
  /// Deletes the GL objects (the context must be current).
  void release(const GlApi& gl);
  /// The colour buffer as an RGB image, top row first.
  Image read_rgb(const GlApi& gl, const char* who) const;
};

}  // namespace terralod::render::detail
