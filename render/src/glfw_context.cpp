// The windowed OpenGL context: a GLFW window with a core 3.3 context (X11 or Wayland).
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include <cstdio>
#include <mutex>
#include <string>

#include "terralod/render/gl_context.hpp"

namespace terralod::render {
namespace {

// GLFW is initialised with the first window and terminated with the last one.
std::mutex g_glfw_mutex;
int g_glfw_windows = 0;
thread_local std::string g_glfw_error;

void on_glfw_error(int code, const char* description) {
  char buf[32];
  std::snprintf(buf, sizeof buf, " (GLFW error 0x%x)", unsigned(code));
  g_glfw_error = std::string(description ? description : "unknown error") + buf;
}

void* glfw_proc(const char* name) { return reinterpret_cast<void*>(glfwGetProcAddress(name)); }

std::string last_glfw_error() { return g_glfw_error.empty() ? std::string("unknown error") : g_glfw_error; }

}  // namespace

std::unique_ptr<WindowContext> WindowContext::create(const WindowOptions& o) {
  if (o.width < 1 || o.height < 1)
    throw RenderError("GLFW: window size " + std::to_string(o.width) + " x " + std::to_string(o.height) +
                      " must be at least 1 x 1");
  GLFWwindow* w = nullptr;
  {
    std::lock_guard<std::mutex> lock(g_glfw_mutex);
    glfwSetErrorCallback(&on_glfw_error);
    g_glfw_error.clear();
    if (g_glfw_windows == 0 && !glfwInit())
      throw RenderError("GLFW: cannot initialise: " + last_glfw_error());
    glfwDefaultWindowHints();
    glfwWindowHint(GLFW_CLIENT_API, GLFW_OPENGL_API);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    glfwWindowHint(GLFW_VISIBLE, o.visible ? GLFW_TRUE : GLFW_FALSE);
    glfwWindowHint(GLFW_RESIZABLE, o.resizable ? GLFW_TRUE : GLFW_FALSE);
    glfwWindowHint(GLFW_DEPTH_BITS, 24);
    glfwWindowHint(GLFW_SAMPLES, 0);
    w = glfwCreateWindow(o.width, o.height, o.title.c_str(), nullptr, nullptr);
    if (!w) {
      const std::string why = last_glfw_error();
      if (g_glfw_windows == 0) glfwTerminate();
      throw RenderError("GLFW: cannot open a " + std::to_string(o.width) + " x " + std::to_string(o.height) +
                        " window with an OpenGL 3.3 core context: " + why);
    }
    ++g_glfw_windows;
  }
  std::unique_ptr<WindowContext> ctx(new WindowContext(w));  // from here on the destructor cleans up
  ctx->make_current();
  glfwSwapInterval(o.vsync ? 1 : 0);
  ctx->load(&glfw_proc, "glfw");
  return ctx;
}

WindowContext::WindowContext(GLFWwindow* window) : window_(window) {}

WindowContext::~WindowContext() {
  std::lock_guard<std::mutex> lock(g_glfw_mutex);
  if (glfwGetCurrentContext() == window_) glfwMakeContextCurrent(nullptr);
  glfwDestroyWindow(window_);
  if (--g_glfw_windows == 0) glfwTerminate();
}

void WindowContext::make_current() {
  if (glfwGetCurrentContext() != window_) glfwMakeContextCurrent(window_);
}

void WindowContext::swap_buffers() { glfwSwapBuffers(window_); }

int WindowContext::framebuffer_width() const {
  int w = 0, h = 0;
  glfwGetFramebufferSize(window_, &w, &h);
  return w;
}

int WindowContext::framebuffer_height() const {
  int w = 0, h = 0;
  glfwGetFramebufferSize(window_, &w, &h);
  return h;
}

bool WindowContext::should_close() const { return glfwWindowShouldClose(window_) != 0; }

void WindowContext::poll_events() { glfwPollEvents(); }

}  // namespace terralod::render
