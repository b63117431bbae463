// The --texture-db / --layer / --lens options shared by `terralod view` and `terralod-fly`:
// parses the layer specs and sets up what LayeredRenderer needs to draw a terrain with the
// texture layers stored in a block database (texture_store.hpp).
//
// Usage:
//   auto setup = terralod::cli::LayerSetup::open("terrain.db", {"shade", "bands:multiply:0.8"},
//                                                terralod::cli::parse_lens("--lens", "7000,9000,800"));
//   setup.wait_loaded(60000);                        // tools and headless runs; a frame never waits
//   terralod::render::LayeredRenderer r(ctx);
//   setup.attach(r);                                 // the lens texture
//   terralod::render::LayeredItem item{r.upload(draw_mesh), setup.bindings(r)};
//   r.draw(camera, setup.styles(), setup.lens(), {item});
//
// Contract:
//   - A spec is NAME[:OP[:WEIGHT[:lens]]]: NAME a layer stored in the database; OP one of
//     blend (default), add, subtract, multiply; WEIGHT in [0,1] (default 1); the literal "lens"
//     masks the layer by the highlight lens (drawn only inside it). A layer whose kind is
//     "shading" is topographic: when it is on, the terrain is drawn in decal mode (no
//     per-vertex lighting). Bad specs throw UsageError naming the spec.
//   - Whole-layer mode (a terrain that is not a block database): each distinct layer is drawn
//     from one texture: the finest pyramid level whose sides are at most max_texture_size,
//     covering the layer's georef. It is read from the database on a worker thread of a
//     TextureCache (key: layer index, node = the level); until it is resident the layer has no
//     data (drawn transparent). The same name given twice shares it.
//   - Per-patch mode (open() given the drawn terrain's approximation tree: `terralod view --db`,
//     `terralod-fly --db`): each distinct layer's texture tree is built over that tree from
//     the layer's record, and every drawn node gets its patch by gamma (patch_textures.hpp:
//     the parent's patch while one loads; the resident texture memory within budget_bytes,
//     gamma raised for the frame when needed). The layers must have patch tiles (stored by
//     `terralod texture` on a database with its tree), and the texture database's tree must
//     be the drawn one (DatabaseError naming the file otherwise).
//       auto setup = LayerSetup::open("terrain.db", specs, lens, {}, &domains);
//       const auto& f = setup.patch_frame(view, drawn.triangle_node);  // order triangles by f
//       auto items = setup.items(renderer, mesh_id, f);                   // one per group
//   - --lens X,Y,RADIUS: world metres, RADIUS > 0; the lens covers the square of side 2 RADIUS
//     centred on (X, Y) with the round texture of render::make_lens_texture.
//   - Not thread-safe (one render thread); the cache's workers are internal.
//   - Memory: whole-layer mode: each layer's chosen level, 4 bytes per texel, once in the cache
//     and once on the GPU; per-patch mode: at most budget_bytes in the cache and as much on the
//     GPU (LayeredRendererOptions::texture_budget_bytes is set to it by attach()).
#pragma once

#include <cstddef>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "cli_common.hpp"
#include "terralod/pm/view.hpp"
#include "terralod/render/layered_renderer.hpp"
#include "terralod/render/patch_textures.hpp"
#include "terralod/render/texture_cache.hpp"
#include "terralod/render/texture_layers.hpp"
#include "terralod/render/texture_store.hpp"

namespace terralod::cli {

struct LayerSpec {
  std::string name;
  render::LayerOp op = render::LayerOp::Blend;
  float weight = 1.0f;
  bool lens = false;  ///< masked by the highlight lens
};

/// Parses NAME[:OP[:WEIGHT[:lens]]] (see the contract); UsageError on a bad spec.
LayerSpec parse_layer_spec(const std::string& text);

struct LensSpec {
  double x = 0, y = 0, radius = 0;  ///< world metres; radius > 0
};
/// Parses X,Y,RADIUS given to `option`; UsageError on bad text.
LensSpec parse_lens(const std::string& option, const std::string& text);

struct LayerSetupOptions {
  int max_texture_size = 4096;                        ///< pixels per side of a layer's texture, >= 1
  std::size_t budget_bytes = std::size_t(512) << 20;  ///< texture cache budget
  int lens_texture_size = 128;                        ///< pixels per side of the lens texture
  double gamma_px = 1.0;  ///< per-patch mode: texel area on screen, pixels^2 (> 0)
};

/// LayerSetupOptions from --gamma (pixels^2, default 1) and --texture-memory (megabytes,
/// default 536.870912 = 512 MiB), the options `terralod view` and `terralod-fly` share;
/// UsageError for a value that is not > 0.
LayerSetupOptions layer_setup_options(const Args& a);

/// The option specs that layer_setup_options reads (--texture-db, --layer, --lens, --gamma,
/// --texture-memory), for the commands that draw texture layers (terralod view, terralod-fly).
std::vector<OptionSpec> layer_option_specs();

class LayerSetup {
 public:
  /// Opens the database read-only, reads the records of the named layers (DatabaseError when
  /// one is missing) and queues the loads of their textures.
  /// `drawn_tree` (the approximation tree of the drawn terrain, render::patch_domains of its
  /// nodes) selects per-patch mode.
  static LayerSetup open(const std::string& db_path, const std::vector<std::string>& specs,
                         std::optional<LensSpec> lens, const LayerSetupOptions& options = {},
                         const std::vector<render::PatchDomain>* drawn_tree = nullptr);

  /// The styles, one per spec (in order); toggle `enabled` freely between frames.
  std::vector<render::LayerStyle>& styles() { return styles_; }
  const std::vector<render::LayerStyle>& styles() const { return styles_; }
  const std::vector<LayerSpec>& specs() const { return specs_; }
  /// The lens (disabled when no --lens was given until enabled); move it with move_lens.
  render::Lens& lens() { return lens_; }
  double lens_radius() const { return lens_radius_; }
  /// Radius (world metres, > 0) of the lens square's half side; keeps its centre.
  void set_lens_radius(double radius);
  void move_lens(double x, double y);

  /// Sets the renderer's lens texture (once per renderer).
  void attach(render::LayeredRenderer& renderer) const;
  /// The bindings of this frame, one per style: the layer's texture once resident (uploaded on
  /// first use through renderer.texture_for), texture 0 until then. Never waits.
  std::vector<render::LayerBinding> bindings(render::LayeredRenderer& renderer);
  /// Per-patch mode: the frame's texture groups over the drawn mesh's triangles (their nodes),
  /// for the enabled styles. Never waits.
  /// wait (tools, headless runs): until every wanted patch is resident, so the frame shows what
  /// gamma asks for (at most 64 rounds of loads; a failed load throws as wait_loaded does).
  const render::PatchTextureFrame& patch_frame(const pm::View& view,
                                               std::span<const std::int64_t> triangle_node,
                                               bool wait = false);
  /// Per-patch mode: one item per group of `frame`, drawing the group's range of `mesh` (whose
  /// triangles must be in frame.triangle_order), textures uploaded on first use.
  std::vector<render::LayeredItem> items(render::LayeredRenderer& renderer, render::MeshId mesh,
                                         const render::PatchTextureFrame& frame);
  bool per_patch() const { return patches_ != nullptr; }
  /// Blocks until every enabled layer's texture is resident or failed, or timeout_ms passed;
  /// throws std::runtime_error with the loader's message when a load failed. Per-patch mode:
  /// until the loads queued so far are done (the next patch_frame may queue more).
  void wait_loaded(int timeout_ms);
  /// Texture bytes resident in the cache.
  std::size_t resident_bytes() const { return cache().stats().resident_bytes; }
  std::size_t budget_bytes() const { return budget_bytes_; }
  /// Per-patch mode: the gamma asked for (a frame may raise it for the budget).
  double gamma_px() const { return patches_ ? patches_->options().gamma_px : 0.0; }

 private:
  LayerSetup() = default;
  void open_patches(const blocks::BlockDatabase& db, const std::vector<render::PatchDomain>& drawn_tree,
                    const LayerSetupOptions& options);
  std::string db_path_;
  std::vector<LayerSpec> specs_;
  std::vector<render::LayerStyle> styles_;
  std::vector<int> layer_of_;                 ///< spec -> distinct layer index
  std::vector<render::LayerRecord> records_;  ///< per distinct layer
  std::vector<int> levels_;                   ///< chosen pyramid level per distinct layer
  const render::TextureCache& cache() const { return patches_ ? patches_->cache() : *cache_; }
  std::unique_ptr<render::TextureCache> cache_;     ///< whole-layer mode
  std::unique_ptr<render::PatchTextures> patches_;  ///< per-patch mode
  std::size_t budget_bytes_ = 0;
  render::Lens lens_;
  double lens_radius_ = 0;
  int lens_texture_size_ = 128;
};

}  // namespace terralod::cli
