// terralod-fly's single-PM terrain: one progressive mesh of the whole terrain (a DEM built in
// memory, a .pm file or the built-in generated terrain) refined by pm::SelectiveRefinement, its
// displayed mesh converted for the GPU with the normals of the full-resolution samples.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <memory>
#include <string>
#include <vector>

#include "cli_common.hpp"
#include "fly_source.hpp"
#include "terrain_input.hpp"
#include "terralod/blocks/ground_scale.hpp"
#include "terralod/pm/collapse_dag.hpp"
#include "terralod/pm/height_query.hpp"
#include "terralod/pm/progressive_mesh.hpp"
#include "terralod/pm/terrain_generator.hpp"
#include "terralod/pm/timing.hpp"

namespace terralod::fly {

using namespace terralod::cli;
using Clock = std::chrono::steady_clock;

namespace {

using pm::thread_cpu_ms;

// Bilinear ground of a heightfield, the terrain's low point where it has only holes.
double ground_of(const pm::Heightfield& hf, double x, double y, double fallback) {
  const double z = pm::bilinear_height(hf, x, y);
  return std::isfinite(z) ? z : fallback;
}

// One progressive mesh of the whole terrain, refined by pm::SelectiveRefinement.
class PmSource final : public LodSource {
 public:
  PmSource(pm::ProgressiveMesh mesh, const pm::RefinementOptions& o)
      : pm_(std::move(mesh)), ground_(blocks::GroundScaleMap::of(pm_.heightfield())) {
    dag_ = std::make_unique<pm::CollapseDag>(pm_);
    sel_ = std::make_unique<pm::SelectiveRefinement>(*dag_, o);
    const pm::Heightfield& hf = pm_.heightfield();
    const auto [zmin, zmax] = cli::height_range(hf);
    ext_ = make_extent(hf.transform, hf.width(), hf.height(), zmin, zmax, hf.source);
    normals_.resize(hf.size() * 3);
    for (int r = 0; r < hf.height(); ++r)
      for (int c = 0; c < hf.width(); ++c) {
        const glm::dvec3 n = render::heightfield_normal(hf, c, r);
        float* p = &normals_[(std::size_t(r) * hf.width() + c) * 3];
        p[0] = float(n.x), p[1] = float(n.y), p[2] = float(n.z);
      }
  }
  const Extent& extent() const override { return ext_; }
  double ground(double x, double y) const override { return ground_of(pm_.heightfield(), x, y, ext_.zmin); }
  double ceiling(double x, double y) const override { return ground(x, y); }
  // The frame's ground scale at the eye (as a database's runtime sets it), then the clip
  // planes: reverse-Z depth keeps precision with a near plane close to the eye; the far plane
  // is twice the extent, beyond what the ground scale (within a few per cent of 1) stretches.
  void fit_camera(pm::Camera& c) const override {
    c.ground = ground_.at(c.x, c.y);
    const double above = c.z - ground(c.x, c.y);
    c.near_m = std::clamp(0.25 * std::max(above, 0.0), 0.1, 100.0);
    const double extent = ext_.transform.spacing_x() * ext_.width + ext_.transform.spacing_y() * ext_.height;
    c.far_m = std::max(c.near_m * 2.0, 2.0 * extent + std::fabs(c.z - ext_.zmin) * 2.0);
  }
  pm::RefinementOptions options() const override { return sel_->options(); }
  void set_options(const pm::RefinementOptions& o) override { sel_->set_options(o); }
  std::size_t budget_share(std::size_t budget) const override { return budget; }
  const pm::ProgressiveMesh& pm() const { return pm_; }

  bool update(const pm::Camera& c, double time_s, bool /*wait*/, FrameRecord& r,
              render::DrawMesh& dm) override {
    const double cpu0 = thread_cpu_ms();
    const pm::FrameStats& s = sel_->update(pm::View(c), time_s);
    blocks::RuntimeFrameStats& l = r.lod;
    l.update_cpu_ms = thread_cpu_ms() - cpu0;
    l.update_ms = s.update_ms, l.moving_vertices = s.morphing;
    l.bound_px = s.bound_px, l.tolerance_px = s.tolerance_px, l.triangles = s.triangles;
    l.pm_blocks = l.blocks_resident = l.nodes_resident = l.nodes_visited = 1;
    // The displayed mesh (geomorph positions) relative to the origin, normals of the
    // full-resolution samples, triangles CCW seen from above.
    const auto t0 = Clock::now();
    const pm::RenderMesh m = sel_->render_mesh();
    render::fill_draw_geometry(m.positions, m.triangles, ext_.origin, ext_.transform.determinant() < 0, dm);
    dm.normals.resize(m.positions.size() * 3);
    for (std::size_t v = 0; v < m.positions.size(); ++v)
      std::copy_n(&normals_[std::size_t(m.samples[v]) * 3], 3, &dm.normals[3 * v]);
    r.upload_ms = ms_since(t0);
    return true;
  }

 private:
  pm::ProgressiveMesh pm_;
  blocks::GroundScaleMap ground_;  // of the PM's heightfield: the identity without a CRS
  std::unique_ptr<pm::CollapseDag> dag_;
  std::unique_ptr<pm::SelectiveRefinement> sel_;
  std::vector<float> normals_;  // per sample, world frame
  Extent ext_;
};

}  // namespace

std::unique_ptr<LodSource> open_pm_source(const std::string& input, int generated_size,
                                          const pm::RefinementOptions& o, const blocks::DemOptions& dem) {
  const auto t0 = Clock::now();
  pm::BuildOptions b;
  b.parallel_strips = false;  // no full-resolution cut column in the view-dependent mesh
  pm::ProgressiveMesh mesh = [&] {
    if (!input.empty()) return pm_input_stage(input, dem, b);
    const pm::Heightfield hf = pm::generate_terrain(demo_terrain_options(generated_size));
    std::printf("terrain: the built-in generated terrain, %d x %d samples\n", hf.width(), hf.height());
    return build_stage(hf, b);
  }();
  auto src = std::make_unique<PmSource>(std::move(mesh), o);
  const Extent& e = src->extent();
  std::printf("terrain: %s, %d x %d samples, %zu vsplits, heights %.1f..%.1f m, ready in %s\n",
              e.name.c_str(), e.width, e.height, src->pm().vsplit_count(), e.zmin, e.zmax,
              format_duration(ms_since(t0)).c_str());
  return src;
}

}  // namespace terralod::fly
