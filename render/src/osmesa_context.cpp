// The offscreen OpenGL context: OSMesa rendering into a memory buffer, no display needed.
#include <GL/osmesa.h>

#include <cstdint>
#include <string>
#include <vector>

#include "terralod/render/gl_context.hpp"

namespace terralod::render {
namespace {

void* osmesa_proc(const char* name) { return reinterpret_cast<void*>(OSMesaGetProcAddress(name)); }

class OffscreenContext final : public GlContext {
 public:
  explicit OffscreenContext(const OffscreenOptions& o) : width_(o.width), height_(o.height) {
    if (o.width < 1 || o.height < 1 || o.width > 16384 || o.height > 16384)
      throw RenderError("osmesa: framebuffer size " + std::to_string(o.width) + " x " +
                        std::to_string(o.height) + " is outside 1..16384");
    std::string tried;
#ifdef OSMESA_CONTEXT_MAJOR_VERSION
    // Core profile 3.3 or newer (Mesa >= 12).
    const int core[] = {OSMESA_FORMAT,
                        OSMESA_RGBA,
                        OSMESA_DEPTH_BITS,
                        24,
                        OSMESA_STENCIL_BITS,
                        0,
                        OSMESA_PROFILE,
                        OSMESA_CORE_PROFILE,
                        OSMESA_CONTEXT_MAJOR_VERSION,
                        3,
                        OSMESA_CONTEXT_MINOR_VERSION,
                        3,
                        0};
    ctx_ = OSMesaCreateContextAttribs(core, nullptr);
    tried = "core 3.3 (OSMesaCreateContextAttribs)";
#endif
    if (!ctx_) {
      // The best compatibility context this OSMesa gives; load() refuses it if below 3.3.
      ctx_ = OSMesaCreateContextExt(OSMESA_RGBA, 24, 0, 0, nullptr);
      tried += std::string(tried.empty() ? "" : ", then ") + "compatibility (OSMesaCreateContextExt)";
    }
    if (!ctx_) throw RenderError("osmesa: cannot create a context; tried " + tried);
    buffer_.assign(std::size_t(width_) * height_ * 4, 0);
    try {
      make_current();
      load(&osmesa_proc, "osmesa");
    } catch (...) {
      OSMesaDestroyContext(ctx_);
      throw;
    }
  }
  ~OffscreenContext() override {
    if (OSMesaGetCurrentContext() == ctx_) OSMesaMakeCurrent(nullptr, nullptr, GL_UNSIGNED_BYTE, 0, 0);
    OSMesaDestroyContext(ctx_);
  }

  void make_current() override {
    if (OSMesaGetCurrentContext() == ctx_) return;
    if (!OSMesaMakeCurrent(ctx_, buffer_.data(), GL_UNSIGNED_BYTE, width_, height_))
      throw RenderError("osmesa: OSMesaMakeCurrent failed");
  }
  void swap_buffers() override {}
  int framebuffer_width() const override { return width_; }
  int framebuffer_height() const override { return height_; }

 private:
  OSMesaContext ctx_ = nullptr;
  int width_, height_;
  std::vector<std::uint8_t> buffer_;
};

}  // namespace

std::unique_ptr<GlContext> create_offscreen_context(const OffscreenOptions& options) {
  return std::make_unique<OffscreenContext>(options);
}

}  // namespace terralod::render
