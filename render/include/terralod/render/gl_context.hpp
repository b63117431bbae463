// OpenGL contexts for terralod: an offscreen one (OSMesa, no display needed) and a window (GLFW).
//
// Usage:
//   auto ctx = terralod::render::create_offscreen_context();          // OSMesa, core 3.3+
//   std::printf("%s\n", ctx->info().renderer.c_str());                // "llvmpipe (LLVM 15...)"
//   terralod::render::TerrainRenderer r(*ctx);                         // see terrain_renderer.hpp
//
//   terralod::render::WindowOptions w;  w.width = 1280;  w.height = 720;
//   auto win = terralod::render::WindowContext::create(w);             // needs an X display
//   while (!win->should_close()) { /* r.draw(...); r.present(); */ win->poll_events(); }
//
// Contract:
//   - Both kinds ask for an OpenGL 3.3 core profile. OSMesa: OSMesaCreateContextAttribs with
//     OSMESA_PROFILE = core, version 3.3 (Mesa 22 returns 4.5 core on llvmpipe); where that
//     is missing or fails, the best compatibility context OSMesa gives. Either way a context
//     below 3.3 (no GLSL 330, no VAOs) is refused with RenderError naming the version found.
//   - GL functions are loaded from the context itself (OSMesaGetProcAddress,
//     glfwGetProcAddress); terralod links neither libGL nor libOpenGL, so an offscreen process
//     never touches X11 or GLVND.
//   - A context belongs to the thread that created it; GLFW windows must be created, polled
//     and destroyed on the main thread (a GLFW rule). The renderer makes its context current
//     before each call, so several contexts can be used in turn from one thread.
//   - Failures (no display, no OSMesa, version too low, missing entry points) throw
//     RenderError whose message says which back-end failed and why.
//   - Memory: the offscreen context keeps a width x height RGBA8 buffer (its default
//     framebuffer); the renderer draws into its own framebuffer object in both kinds.
#pragma once

#include <memory>
#include <stdexcept>
#include <string>

struct GLFWwindow;

namespace terralod::render {

namespace detail {
struct GlApi;  // table of loaded GL entry points (render/src/gl_api.hpp)
}

/// Any failure of the GL back-end: context creation, shader compilation, framebuffers.
class RenderError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// What the driver reports about a context.
struct GlInfo {
  std::string backend;                                  ///< "osmesa" or "glfw"
  std::string vendor, renderer, version, glsl_version;  ///< glGetString values
  int major = 0, minor = 0;                             ///< GL version numbers
  bool core_profile = false;
  bool clip_control = false;  ///< glClipControl available (GL 4.5 or ARB_clip_control): reverse-Z depth
};

/// An OpenGL context the renderer can draw with. Not copyable; owns its GL objects' namespace.
class GlContext {
 public:
  GlContext(const GlContext&) = delete;
  GlContext& operator=(const GlContext&) = delete;
  virtual ~GlContext();

  /// Makes this context current on the calling thread (cheap when it already is).
  virtual void make_current() = 0;
  /// Shows the default framebuffer (window) — a no-op offscreen.
  virtual void swap_buffers() = 0;
  /// Size of the default framebuffer in pixels (the window's drawable, or the OSMesa buffer).
  virtual int framebuffer_width() const = 0;
  virtual int framebuffer_height() const = 0;

  const GlInfo& info() const { return info_; }
  /// Loaded GL entry points; for terralod's own renderer code (the type is private).
  const detail::GlApi& api() const { return *api_; }

 protected:
  GlContext();
  /// Loads the entry points with `get_proc` (context must be current) and fills info();
  /// throws RenderError when a required one is missing or the version is below 3.3.
  void load(void* (*get_proc)(const char* name), const std::string& backend);

 private:
  std::unique_ptr<detail::GlApi> api_;
  GlInfo info_;
};

/// Options of the offscreen (OSMesa) context.
struct OffscreenOptions {
  int width = 1024;  ///< default framebuffer size, pixels, 1..16384
  int height = 768;
};

/// An OSMesa context rendering into memory; needs no display. Throws RenderError on failure.
std::unique_ptr<GlContext> create_offscreen_context(const OffscreenOptions& options = {});

/// Options of a GLFW window.
struct WindowOptions {
  int width = 1280;  ///< client area, screen coordinates, >= 1
  int height = 720;
  std::string title = "terralod";
  bool visible = true;  ///< false: a hidden window (still a real drawable)
  bool vsync = true;    ///< swap interval 1 (true) or 0
  bool resizable = true;
};

/// A GLFW window with its OpenGL context.
class WindowContext : public GlContext {
 public:
  /// Opens a window (glfwInit on first use; glfwTerminate when the last window closes).
  /// Throws RenderError("GLFW: ...") when there is no display or no suitable context.
  static std::unique_ptr<WindowContext> create(const WindowOptions& options = {});
  ~WindowContext() override;

  void make_current() override;
  void swap_buffers() override;
  int framebuffer_width() const override;
  int framebuffer_height() const override;

  /// True once the user asked to close the window.
  bool should_close() const;
  /// Processes pending window events (input callbacks run from here).
  void poll_events();
  /// The GLFW handle, for installing input callbacks; owned by this object.
  GLFWwindow* glfw_window() const { return window_; }

 private:
  explicit WindowContext(GLFWwindow* window);
  GLFWwindow* window_ = nullptr;
};

}  // namespace terralod::render
