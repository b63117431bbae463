// A GoogleTest fixture owning an offscreen OpenGL context (OSMesa) of W x H pixels; the test is
// skipped, with the reason, where no context can be made.
//
// Usage:
//   struct Gl : terralod::test::OffscreenGl<64, 64> {};
//   TEST_F(Gl, Draws) { terralod::render::LayeredRenderer r(*ctx); ... }
#pragma once

#include <gtest/gtest.h>

#include <memory>

#include "terralod/render/gl_context.hpp"

namespace terralod::test {

template <int W, int H>
struct OffscreenGl : ::testing::Test {
  std::unique_ptr<render::GlContext> ctx;
  void SetUp() override {
    try {
      ctx = render::create_offscreen_context({W, H});
    } catch (const render::RenderError& e) {
      GTEST_SKIP() << "no OSMesa context: " << e.what();
    }
  }
};

}  // namespace terralod::test
