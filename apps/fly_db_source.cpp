// terralod-fly's streamed terrain: a block database through blocks::TerrainRuntime (the
// approximation tree from its root, PM blocks loaded by a background thread within the memory
// budget), its drawn mesh handed to the GPU only when it changed.
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "cli_common.hpp"
#include "fly_source.hpp"

namespace terralod::fly {

using namespace terralod::cli;
using Clock = std::chrono::steady_clock;

namespace {

// Bitwise equality of two arrays of plain values.
template <class T>
bool same_bytes(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

// The runtime's options with the live ones of `o` (tau, the budget mode, the geomorph time).
void with_refinement(blocks::RuntimeOptions& ro, const pm::RefinementOptions& o) {
  ro.tolerance_px = o.tolerance_px;
  ro.target_triangles = o.target_triangles;
  ro.morph_seconds = o.morph_seconds;
}

// A block database through blocks::TerrainRuntime (the tree from its root, PM blocks streamed).
class DbSource final : public LodSource {
 public:
  DbSource(const std::string& path, const pm::RefinementOptions& o, const blocks::RuntimeOptions& base)
      : path_(path) {
    const auto t0 = Clock::now();
    blocks::RuntimeOptions ro = base;
    with_refinement(ro, o);
    rt_ = std::make_unique<blocks::TerrainRuntime>(path, ro);
    opt_ = o;
    const blocks::BlockGrid& g = rt_->grid();
    const pm::Box& box = rt_->terrain_box();
    ext_ = make_extent(g.transform(), g.grid_width(), g.grid_height(), box.lo.z, box.hi.z, path);
    std::printf(
        "terrain: %s, %d x %d samples in %d x %d blocks of %d, tree of %zu nodes, heights %.1f..%.1f m, "
        "ready in %s\n",
        path.c_str(), g.grid_width(), g.grid_height(), g.cols(), g.rows(), g.block_size(), rt_->tree().size(),
        box.lo.z, box.hi.z, format_duration(ms_since(t0)).c_str());
  }
  const Extent& extent() const override { return ext_; }
  pm::RefinementOptions options() const override { return opt_; }
  // Live: tau, the budget mode and the geomorph time apply from the next frame; nothing is
  // read again.
  void set_options(const pm::RefinementOptions& o) override {
    opt_ = o;
    blocks::RuntimeOptions ro = rt_->options();
    with_refinement(ro, o);
    rt_->set_options(ro);
  }
  // The runtime regulates tau over the whole frame.
  std::size_t budget_share(std::size_t budget) const override { return budget; }
  // The surface as drawn last frame (the terrain's low point where nothing is drawn).
  double ground(double x, double y) const override {
    const double z = rt_->drawn_height(x, y);
    return std::isfinite(z) ? z : ext_.zmin;
  }
  // The highest sample under (x, y) that the tree knows without loading anything.
  double ceiling(double x, double y) const override { return rt_->max_height_at(x, y); }
  std::span<const std::int64_t> triangle_nodes() const override { return rt_->drawn_mesh().triangle_node; }
  void fit_camera(pm::Camera& c) const override { rt_->fit_camera(c); }
  const blocks::TerrainRuntime* runtime() const override { return rt_.get(); }

  bool update(const pm::Camera& c, double time_s, bool wait, FrameRecord& r, render::DrawMesh& dm) override {
    const pm::View view(c);
    r.streamed = true;
    if (wait) {
      // Headless: the frames must not depend on the loader thread's timing.
      const auto w0 = Clock::now();
      const blocks::RuntimeFrameStats first = rt_->update_until_loaded(view, time_s);
      r.wait_ms = ms_since(w0) - first.update_ms;
      r.lod = rt_->stats();
      // The work of the frame is the first update's (the others only pick up loads).
      r.lod.update_ms = first.update_ms, r.lod.update_cpu_ms = first.update_cpu_ms;
    } else {
      r.lod = rt_->update(view, time_s);
    }
    const auto t0 = Clock::now();
    const blocks::DrawnMesh& m = rt_->drawn_mesh();
    if (built_ && same_bytes(m.positions, prev_positions_) && same_bytes(m.triangles, prev_triangles_))
      return false;  // nothing moved: keep the uploaded mesh
    built_ = true;
    prev_positions_ = m.positions, prev_triangles_ = m.triangles;
    render::fill_draw_mesh(m, ext_.origin, ext_.transform.determinant() < 0, dm);
    r.upload_ms = ms_since(t0);
    return true;
  }

 private:
  std::string path_;
  pm::RefinementOptions opt_;
  std::unique_ptr<blocks::TerrainRuntime> rt_;
  Extent ext_;
  std::vector<pm::Vec3> prev_positions_;
  std::vector<std::array<std::uint32_t, 3>> prev_triangles_;
  bool built_ = false;
};

}  // namespace

std::unique_ptr<LodSource> open_db_source(const std::string& path, const pm::RefinementOptions& o,
                                          const blocks::RuntimeOptions& base) {
  return std::make_unique<DbSource>(path, o, base);
}

}  // namespace terralod::fly
