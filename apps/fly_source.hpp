// terralod-fly's terrains: what its frame loop needs from the level of detail of a single
// progressive mesh (fly_pm_source.cpp) or of a streamed block database (fly_db_source.cpp), and
// the per-frame record both fill.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <utility>

#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/terrain_runtime.hpp"
#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/selective_refinement.hpp"
#include "terralod/pm/view.hpp"
#include "terralod/render/draw_mesh.hpp"

namespace terralod::fly {

// The terrain's grid and height range; the drawn mesh's vertices are relative to `origin`.
struct Extent {
  pm::GridTransform transform;
  int width = 0, height = 0;  // samples
  double zmin = 0, zmax = 0;
  glm::dvec3 origin{0.0};  // grid centre at mid height
  std::string name;

  double side_x() const { return transform.spacing_x() * (width - 1); }
  double side_y() const { return transform.spacing_y() * (height - 1); }
  std::pair<double, double> centre() const {
    return transform.to_world((width - 1) / 2.0, (height - 1) / 2.0);
  }
};

// An Extent with its origin at the grid's centre and mid height.
inline Extent make_extent(const pm::GridTransform& t, int width, int height, double zmin, double zmax,
                          std::string name) {
  Extent e{t, width, height, zmin, zmax, {}, std::move(name)};
  const auto [cx, cy] = e.centre();
  e.origin = {cx, cy, 0.5 * (zmin + zmax)};
  return e;
}

// One frame: the level of detail's statistics (the runtime's; a single PM fills the same
// fields as one PM block) and the drawing's.
struct FrameRecord {
  pm::Camera camera;
  blocks::RuntimeFrameStats lod;
  bool streamed = false;  // --db: a block database through the runtime
  double draw_ms = 0, upload_ms = 0, wait_ms = 0;
  std::size_t vertices = 0;
  std::size_t texture_bytes = 0;                              // resident in the texture cache
  std::size_t texture_patches = 0, textures_from_parent = 0;  // per-patch textures (--db)
};

// The level-of-detail side of a frame: one selection update and the mesh it draws.
class LodSource {
 public:
  virtual ~LodSource() = default;
  virtual const Extent& extent() const = 0;
  // Height of the terrain under world (x, y), metres (clamped to the terrain).
  virtual double ground(double x, double y) const = 0;
  // A height at or above the terrain under world (x, y) known without loading anything (the
  // built-in flight's reference: it never goes underground).
  virtual double ceiling(double x, double y) const = 0;
  // Sets the camera's near and far planes and its ground scale for this terrain (the selection
  // and the picture use the same camera, so the bound is true of the picture). Both set the
  // frame's ground scale at the eye (TerrainRuntime::fit_camera, blocks::GroundScaleMap): the
  // identity without a CRS.
  virtual void fit_camera(pm::Camera& c) const = 0;
  // Runs this frame's selection at time_s; fills r's level-of-detail fields; rewrites `mesh`
  // (origin = extent().origin, CCW from above) and returns true when the drawn mesh changed.
  // wait: finish the loads this frame asks for before returning (headless determinism).
  // r.upload_ms: the time spent making `mesh` (the caller adds the GPU upload).
  virtual bool update(const pm::Camera& c, double time_s, bool wait, FrameRecord& r,
                      render::DrawMesh& mesh) = 0;
  virtual pm::RefinementOptions options() const = 0;
  virtual void set_options(const pm::RefinementOptions& o) = 0;
  // Triangle target of the budget mode for a whole-frame budget (RefinementOptions::target_triangles).
  virtual std::size_t budget_share(std::size_t budget) const = 0;
  // The approximation-tree node of each triangle of the last mesh (empty: no tree).
  virtual std::span<const std::int64_t> triangle_nodes() const { return {}; }
  // The block database's runtime (--db), after update() in the frame's state; nullptr for a
  // single PM.
  virtual const blocks::TerrainRuntime* runtime() const { return nullptr; }
};

// The single-PM terrains (fly_pm_source.cpp): a DEM built in memory (`input` names it), a .pm
// file, or, with `input` empty, the built-in terrain of generated_size samples per side. Prints
// one line (two for the built-in terrain) when ready. `dem`: how the DEM is read (its --crs).
std::unique_ptr<LodSource> open_pm_source(const std::string& input, int generated_size,
                                          const pm::RefinementOptions& o, const blocks::DemOptions& dem);

// A block database through blocks::TerrainRuntime (fly_db_source.cpp): the tree from its root,
// PM blocks streamed within `base`'s budget; tau, budget and geomorphs from `o`. Prints one line.
std::unique_ptr<LodSource> open_db_source(const std::string& path, const pm::RefinementOptions& o,
                                          const blocks::RuntimeOptions& base);

}  // namespace terralod::fly
