// One frame of terralod-fly: selection, upload, draw (see fly_pipeline.hpp).
#include "fly_pipeline.hpp"

#include <chrono>

#include "cli_common.hpp"

namespace terralod::fly {

using cli::ms_since;
using Clock = std::chrono::steady_clock;

void Pipeline::set_layers(render::GlContext& ctx, cli::LayerSetup* layers) {
  layers_ = layers;
  layered_ = std::make_unique<render::LayeredRenderer>(ctx);
  layers_->attach(*layered_);
}

FrameRecord Pipeline::frame(const pm::Camera& cam, double time_s, bool wait) {
  if (!frozen) {
    FrameRecord lod;
    if (src_.update(cam, time_s, wait, lod, dm_)) {
      // The whole mesh is replaced: with --db the runtime's heights already hold the
      // geomorphs, so it is drawn at alpha 0 with no target heights (see the README numbers:
      // replacing costs less than a tenth of the draw on llvmpipe).
      const auto t = Clock::now();
      if (!id_)
        id_ = renderer_.upload(dm_);
      else
        renderer_.replace(*id_, dm_);
      ++version_;
      lod.upload_ms += ms_since(t);
    }
    last_ = lod;
  } else {  // the frozen mesh: no selection work this frame
    last_.lod.update_ms = last_.lod.update_cpu_ms = last_.upload_ms = last_.wait_ms = 0;
  }
  FrameRecord r = last_;
  r.camera = cam;
  r.vertices = dm_.vertex_count();
  const render::Camera& rc = cam;  // one camera type from the selection to the GPU
  drew_layered_ = layers_ && !wireframe;
  if (drew_layered_) {
    if (layers_->per_patch())
      draw_patches(rc, pm::View(cam), wait, r);
    else
      draw_whole_layers(rc, r);
    r.texture_bytes = layers_->resident_bytes();
    return r;
  }
  renderer_.options().wireframe = wireframe;
  r.draw_ms = renderer_.draw(rc, {{*id_, 0.0f}}).draw_ms;
  if (layers_) r.texture_bytes = layers_->resident_bytes();
  return r;
}

void Pipeline::draw_whole_layers(const render::Camera& rc, FrameRecord& r) {
  if (!layered_id_ || layered_version_ != version_) {
    const auto t = Clock::now();
    if (layered_id_) layered_->remove(*layered_id_);
    layered_id_ = layered_->upload(dm_);
    layered_version_ = version_;
    r.upload_ms += ms_since(t);
  }
  const render::LayeredItem item{*layered_id_, layers_->bindings(*layered_)};
  r.draw_ms = layered_->draw(rc, layers_->styles(), layers_->lens(), {item}).draw_ms;
}

void Pipeline::draw_patches(const render::Camera& rc, const pm::View& view, bool wait, FrameRecord& r) {
  const auto t_wait = Clock::now();
  const render::PatchTextureFrame& f = layers_->patch_frame(view, src_.triangle_nodes(), wait);
  if (wait) r.wait_ms += ms_since(t_wait);
  if (!layered_id_ || layered_version_ != version_ || f.triangle_order != layered_order_) {
    const auto t = Clock::now();
    render::order_triangles(dm_, f.triangle_order, sorted_);
    if (layered_id_) layered_->remove(*layered_id_);
    layered_id_ = layered_->upload(sorted_);
    layered_version_ = version_;
    layered_order_ = f.triangle_order;
    r.upload_ms += ms_since(t);
  }
  const std::vector<render::LayeredItem> items = layers_->items(*layered_, *layered_id_, f);
  r.draw_ms = layered_->draw(rc, layers_->styles(), layers_->lens(), items).draw_ms;
  r.texture_patches = f.stats.wanted;
  r.textures_from_parent = f.stats.from_parent;
}

}  // namespace terralod::fly
