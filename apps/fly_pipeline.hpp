// One frame of terralod-fly, window or headless: the terrain's selection (and loads), the upload
// of the mesh it draws, and the draw, plain or with texture layers (whole layers, or per patch
// of a block database's tree).
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "fly_source.hpp"
#include "layer_options.hpp"
#include "terralod/render/gl_context.hpp"
#include "terralod/render/image.hpp"
#include "terralod/render/terrain_renderer.hpp"

namespace terralod::fly {

class Pipeline {
 public:
  Pipeline(LodSource& src, render::GlContext& ctx) : src_(src), renderer_(ctx) {}

  // Texture layers: drawn through a LayeredRenderer on the same context (not in wireframe).
  void set_layers(render::GlContext& ctx, cli::LayerSetup* layers);
  cli::LayerSetup* layers() { return layers_; }
  bool drew_layered() const { return drew_layered_; }
  render::Image read_color() const { return drew_layered_ ? layered_->read_color() : renderer_.read_color(); }

  render::TerrainRenderer& renderer() { return renderer_; }
  /// The renderer that drew the last frame (plain or layered): map objects draw into it.
  render::FrameSource& frame_source() {
    return drew_layered_ ? static_cast<render::FrameSource&>(*layered_) : renderer_;
  }
  LodSource& source() { return src_; }
  bool frozen = false, wireframe = false;

  // wait: headless, the frame waits for its block loads (see LodSource::update).
  FrameRecord frame(const pm::Camera& cam, double time_s, bool wait);

  const render::DrawMesh& draw_mesh() const { return dm_; }

 private:
  // Whole-layer mode: one texture per layer over the whole mesh.
  void draw_whole_layers(const render::Camera& rc, FrameRecord& r);
  // Per-patch mode (--db): the mesh's triangles ordered by the textures of their nodes, one
  // item per group. wait (headless): the frame waits for its wanted patches, so every frame
  // shows the textures gamma asks for and runs are reproducible.
  void draw_patches(const render::Camera& rc, const pm::View& view, bool wait, FrameRecord& r);

  LodSource& src_;
  render::TerrainRenderer renderer_;
  render::DrawMesh dm_;
  std::optional<render::MeshId> id_;
  FrameRecord last_;
  cli::LayerSetup* layers_ = nullptr;
  std::unique_ptr<render::LayeredRenderer> layered_;
  std::optional<render::MeshId> layered_id_;
  std::uint64_t version_ = 0, layered_version_ = 0;
  std::vector<std::uint32_t> layered_order_;  // per-patch mode: the uploaded triangle order
  render::DrawMesh sorted_;
  bool drew_layered_ = false;
};

}  // namespace terralod::fly
