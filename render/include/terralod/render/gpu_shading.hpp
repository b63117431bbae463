// Topographic (shading) textures computed with OpenGL in an offscreen OSMesa context.
//
// The GPU twin of shade_terrain (topographic_texture.hpp): same options, same region, same
// formulas, and results that agree with the CPU within float rounding (tested on N44W072 and on
// a generated terrain). It follows the paper's recipe (Döllner et al., "Texturing techniques
// for terrain visualization", "Generating topographic textures"): the terrain is drawn with an
// orthographic projection into an offscreen framebuffer whose contents are read back, tile by
// tile when the texture is larger than the framebuffer.
//
// Usage:
//   terralod::render::ShadingOptions o;  o.shadows = true;
//   terralod::render::FloatRaster s = terralod::render::shade_terrain_gpu(hf, o);   // own context
//   auto ctx = terralod::render::create_offscreen_context();                      // or reuse one
//   terralod::render::GpuShadingOptions g;  g.max_tile = 512;
//   terralod::render::GpuShadingReport rep;
//   s = terralod::render::shade_terrain_gpu(hf, o, {}, g, ctx.get(), &rep);       // rep.tiles
//
// How (and why this way): the full-resolution heights go to the GPU once as an R32F texture
// (relative to the lowest sample, so float keeps about 0.1 mm on a 2 km relief). Each output
// tile is an FBO with an R32F colour buffer of at most max_tile x max_tile texels (and at most
// GL_MAX_RENDERBUFFER_SIZE / GL_MAX_VIEWPORT_DIMS); one quad covering the tile is drawn with an
// orthographic projection of texel space, so every fragment is exactly one texel. The fragment
// shader reads the 3x3 Horn window with texelFetch (exact samples, no filtering), computes the
// normal and the shade, and marches the shadow ray over the same grid-line crossings as the
// CPU. Computing normals per fragment from the height texture, rather than rasterising the
// full-resolution mesh with per-vertex normals, makes every texel an exact sample of the
// formula (a rasterised mesh would interpolate shades across triangles and the two
// generators could not agree texel by texel). RelativeHeight uses a first pass that writes
// the running row-wise min/max to an RG32F texture, then the column-wise pass per tile.
// The float result is read back with glReadPixels(GL_RED, GL_FLOAT).
//
// Contract:
//   - hf, options, region: as for shade_terrain; same misuse exceptions (std::invalid_argument).
//   - The heightfield must fit in one texture: width and height <= GL_MAX_TEXTURE_SIZE
//     (16384 on llvmpipe), else RenderError names the sizes. Output tiles have no such limit.
//   - context: nullptr creates a private OSMesa context for the call; otherwise any GlContext
//     (OSMesa or a GLFW window), borrowed. The function makes it current, deletes every GL
//     object it made, leaves framebuffer 0 / program 0 / VAO 0 bound and changes the viewport.
//   - Threads: the context's thread; one call at a time per context.
//   - Memory: GPU 4 bytes per sample (heights) + 4 bytes per 16 x 16 cells (shadow index: block
//     maxima, the same skipping as the CPU) + 8 per sample for RelativeHeight + one tile
//     (4 bytes per texel); CPU the output (4 bytes per texel) and one float tile.
//   - Failures of the GL back-end (shader compilation, incomplete framebuffer) throw
//     RenderError with the GL message.
#pragma once

#include <string>

#include "terralod/pm/heightfield.hpp"
#include "terralod/render/gl_context.hpp"
#include "terralod/render/rgba_image.hpp"
#include "terralod/render/topographic_texture.hpp"

namespace terralod::render {

struct GpuShadingOptions {
  int max_tile = 0;  ///< largest tile edge in texels; 0 = as large as the GL limits allow; else >= 1
};

/// What a GPU shading call did.
struct GpuShadingReport {
  int tiles = 0;                        ///< framebuffer tiles rendered
  int tile_width = 0, tile_height = 0;  ///< the tile size used (edge tiles may be smaller)
  std::string renderer;                 ///< GL_RENDERER, e.g. "llvmpipe (LLVM 15.0.6, 256 bits)"
};

/// Shading values in [0, 1] (NaN at holes), top row first: see topographic_texture.hpp.
FloatRaster shade_terrain_gpu(const pm::Heightfield& hf, const ShadingOptions& options = {},
                              const TexelRegion& region = {}, const GpuShadingOptions& gpu = {},
                              GlContext* context = nullptr, GpuShadingReport* report = nullptr);

}  // namespace terralod::render
