// The ground scale of a georeferenced world frame (pm/view.hpp's GroundScale) at any world
// point: what a view needs so that offsets near its eye are ground metres, however far the
// frame's own scale is from 1 there (a continent-wide projection is about 1 % off at its edges).
//
// Usage:
//   const terralod::blocks::GroundScaleMap g = terralod::blocks::GroundScaleMap::of(hf);
//   camera.ground = g.at(camera.x, camera.y);   // then pm::View(camera)
//
// At a world point, G is the symmetric positive part sqrt(J^T J) of the Jacobian J of world
// offsets -> metres on the CRS's ellipsoid: |G v| = |J v|, and J's rotation (the projection's
// convergence), which would turn the view about the eye, is left out. J^T J is the metric of
// the ellipsoid's surface in Earth-centred coordinates, by central differences over +-10 m of
// world offset through GDAL (four points, about 2 us): no singularity at a pole. Outside its box
// the map takes the box's nearest point, so the scale changes continuously as a camera leaves
// the terrain. blocks::TerrainRuntime::fit_camera uses it. Not thread-safe (one GDAL
// transformation): one map per thread.
#pragma once

#include <memory>
#include <optional>
#include <string>

#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/view.hpp"

namespace terralod::blocks {

namespace detail {
class GroundFrame;  // frame_scale.hpp
}  // namespace detail

class GroundScaleMap {
 public:
  /// The identity everywhere.
  GroundScaleMap();
  /// The frame of a grid: (col, row) -> world by `world`, and -> coordinates of `crs_wkt` by
  /// `crs_transform`, over the world box `box` (its x, y). The identity everywhere when there is
  /// no CRS or GDAL cannot map it to its geographic CRS.
  GroundScaleMap(const std::string& crs_wkt, const std::optional<pm::GridTransform>& crs_transform,
                 const pm::GridTransform& world, const pm::Box& box);
  /// hf's frame, over its grid's corners.
  static GroundScaleMap of(const pm::Heightfield& hf);
  GroundScaleMap(GroundScaleMap&&) noexcept;
  GroundScaleMap& operator=(GroundScaleMap&&) noexcept;
  ~GroundScaleMap();

  /// G at world (x, y) (at the box's nearest point when outside it); the identity without a
  /// CRS, or where the frame cannot be transformed or its scale leaves [0.5, 2].
  pm::GroundScale at(double x, double y) const;
  /// False when at() is the identity everywhere (no CRS).
  bool georeferenced() const { return frame_ != nullptr; }

 private:
  std::unique_ptr<detail::GroundFrame> frame_;
  pm::Box box_;
};

}  // namespace terralod::blocks
