// LayeredRenderer: draws terrain patches with any number of texture layers combined on the GPU
// (blend, add, subtract, multiply, alpha masks, a moving highlight lens, key-frame sequences),
// in one pass when the texture units allow and in several passes otherwise.
//
// Usage:
//   auto ctx = terralod::render::create_offscreen_context();
//   terralod::render::LayeredRenderer r(*ctx);
//   terralod::render::MeshId m = r.upload(draw_mesh);                  // see draw_mesh.hpp
//   terralod::render::TextureId shade = r.upload_texture(shade_img);   // RGBA8, counted as uploaded
//   terralod::render::TextureId land = r.upload_texture(landuse_img);
//   r.set_lens_texture(terralod::render::make_lens_texture(128));       // once
//   std::vector<terralod::render::LayerStyle> styles(2);               // see texture_layers.hpp
//   styles[0].topographic = true;  styles[1].op = LayerOp::Multiply;
//   terralod::render::LayeredItem item{m, {{shade, georef}, {land, georef}}};
//   terralod::render::Lens lens{true, lens_rect};        // moving it re-uploads nothing
//   auto stats = r.draw(camera, styles, lens, {item});   // stats.passes, stats.bytes_uploaded
//   terralod::render::Image img = r.read_color();
//
// Contract:
//   - The combination is the one texture_layers.hpp defines (combine_texels), evaluated per
//     fragment in float; the result is clamped after every layer, which is also what the
//     RGBA8 framebuffer does between passes, so one pass and several passes agree up to the
//     8-bit rounding between passes (the tests allow 2 levels per layer). Textures are sampled
//     bilinearly (options.linear_filter) or nearest, clamped to their edge; the lens is
//     transparent outside its rectangle. Lighting: Lambert + ambient from the vertex normals,
//     unless an enabled layer is topographic (decal mode).
//   - One pass when the samplers the enabled layers need (1 per layer, 2 for a sequence
//     layer with a next key frame bound, 1 per mask layer, 1 for the lens) fit
//     texture_units() = min(GL_MAX_TEXTURE_IMAGE_UNITS, options.max_texture_units if > 0, 16);
//     otherwise a base pass, one pass per enabled layer (GL blending does the operation:
//     Blend SRC_ALPHA/ONE_MINUS_SRC_ALPHA, Add ONE/ONE, Subtract REVERSE_SUBTRACT, Multiply
//     DST_COLOR/ZERO) and a lighting pass when lit. Depth test LEQUAL on an invariant position.
//   - LayeredItem::layers has one binding per style (same order); a binding whose texture is
//     0 means the layer has no data on that patch (transparent). georef: the world rectangle
//     the bound texture covers (texture_tree.hpp conventions). Sequences: `next` (the key frame
//     after `texture`, 0 if none) mixed with weight `mix` in [0,1].
//   - An item draws a range of its mesh's triangles (LayeredItem::first_triangle/count).
//   - Items are drawn grouped by their bound textures (FrameStats::texture_binds counts the
//     switches). Texture data is uploaded only by upload_texture/texture_for, never by draw():
//     moving the lens or changing styles, weights or times costs no upload.
//   - Not thread-safe; uses its context (made current in each call), destroy before it.
//     GL failures throw RenderError; bad sizes throw std::invalid_argument.
//   - Memory on the GPU: 24 bytes per vertex + 4 per index; 4 bytes per texel of each texture
//     (no mipmaps); the frame: 8 bytes per pixel.
#pragma once

#include <cstddef>
#include <cstdint>
#include <glm/glm.hpp>
#include <initializer_list>
#include <memory>
#include <span>
#include <vector>

#include "terralod/render/camera.hpp"
#include "terralod/render/draw_mesh.hpp"
#include "terralod/render/gl_context.hpp"
#include "terralod/render/image.hpp"
#include "terralod/render/rgba_image.hpp"
#include "terralod/render/terrain_renderer.hpp"
#include "terralod/render/texture_cache.hpp"
#include "terralod/render/texture_layers.hpp"

namespace terralod::render {

struct LayeredRendererOptions {
  glm::vec3 sky_color{0.62f, 0.75f, 0.88f};
  glm::dvec3 light_direction{-0.5, 0.5, 0.707};  ///< towards the light, world frame
  float ambient = 0.35f;                         ///< [0,1]
  LayerStackOptions stack;                       ///< base colour, lighting on/off
  int max_texture_units = 0;                     ///< 0: the context's limit; smaller values force multi-pass
  bool linear_filter = true;                     ///< false: nearest texel (exact comparisons)
  std::size_t texture_budget_bytes = std::size_t(512) << 20;  ///< texture_for() residency
  bool finish = true;  ///< glFinish at the end of draw() so draw_ms is the frame's cost
};

/// Handle of an uploaded texture; 0 is never valid.
struct TextureId {
  std::uint32_t value = 0;
  bool operator==(const TextureId&) const = default;
};

struct LayerBinding {
  LayerBinding() = default;
  LayerBinding(TextureId t, const GeoRect& g, TextureId next_frame = {}, float next_mix = 0.0f)
      : texture(t), georef(g), next(next_frame), mix(next_mix) {}
  TextureId texture;  ///< 0: no data for this layer on the patch
  GeoRect georef;     ///< world rectangle the texture covers
  TextureId next;     ///< sequences: the next key frame (0: none)
  float mix = 0.0f;   ///< weight of `next`, [0,1]
};

struct LayeredItem {
  MeshId mesh;
  std::vector<LayerBinding> layers;  ///< one per style
  /// The mesh's triangles this item draws: [first_triangle, first_triangle + triangle_count)
  /// clipped to the mesh (the default draws them all). One uploaded mesh whose triangles are
  /// ordered by texture serves many items (patch_textures.hpp).
  std::size_t first_triangle = 0;
  std::size_t triangle_count = ~std::size_t(0);
};

struct LayeredFrameStats {
  std::size_t meshes = 0, triangles = 0;  ///< items drawn (with a triangle), their triangles
  int passes = 0;                         ///< draw passes over the items
  std::size_t texture_binds = 0;          ///< changes of the bound texture set
  std::size_t textures_uploaded = 0;      ///< since the previous draw()
  std::size_t bytes_uploaded = 0;         ///< texture bytes uploaded since the previous draw()
  std::size_t texture_bytes = 0;          ///< texture memory held after this frame
  double draw_ms = 0.0;
};

class LayeredRenderer : public FrameSource {
 public:
  explicit LayeredRenderer(GlContext& context, const LayeredRendererOptions& options = {});
  ~LayeredRenderer();
  LayeredRenderer(const LayeredRenderer&) = delete;
  LayeredRenderer& operator=(const LayeredRenderer&) = delete;

  LayeredRendererOptions& options() { return options_; }
  /// Samplers one pass may use (see the contract).
  int texture_units() const;
  /// Passes a frame with these styles takes (1 = single pass).
  int passes_for(std::span<const LayerStyle> styles, const Lens& lens, bool has_sequences) const;

  MeshId upload(const DrawMesh& mesh);
  void remove(MeshId id);

  TextureId upload_texture(const RgbaImage& image);
  void remove_texture(TextureId id);
  /// The texture of a cache key, uploading `image` on first use (or after eviction); textures
  /// obtained this way not used in the last frame are evicted LRU over texture_budget_bytes.
  TextureId texture_for(const TextureKey& key, const RgbaImage& image);
  bool has_texture(const TextureKey& key) const;
  /// The lens's alpha texture (uploaded once; moving the lens is Lens::rect).
  void set_lens_texture(const RgbaImage& image);
  std::size_t texture_bytes() const;
  std::size_t textures_uploaded_total() const;

  LayeredFrameStats draw(const Camera& camera, std::span<const LayerStyle> styles, const Lens& lens,
                         std::span<const LayeredItem> items);
  LayeredFrameStats draw(const Camera& camera, std::span<const LayerStyle> styles, const Lens& lens,
                         std::initializer_list<LayeredItem> items) {
    return draw(camera, styles, lens, std::span<const LayeredItem>(items.begin(), items.size()));
  }
  /// The last frame's colour, top row first.
  Image read_color() const;
  FrameTarget bind_frame() override;  ///< see FrameSource (no reverse-Z: the layers draw without it)

 private:
  struct Impl;
  GlContext& ctx_;
  LayeredRendererOptions options_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace terralod::render
