// Independent brute-force checker of the screen-space error of a triangle mesh over a
// heightfield, seen by a camera: every vertical error segment projected exactly, in pixels.
//
// Usage:
//   terralod::test::ScreenProjector proj(camera);          // a terralod::pm::Camera (plain data)
//   terralod::test::ScreenCheck c = terralod::test::check_screen_error(hf, sel.mesh(), proj);
//   EXPECT_LE(c.max_error_px, stats.bound_px + 1e-9) << c.describe();
//
// Independence: only the plain data types Camera, Heightfield and TriangleMesh are used; the
// camera matrices are built here with GLM (glm::lookAt, glm::perspective) from the camera
// conventions of view.hpp (yaw clockwise from north, pitch above the horizon, fovy across the
// image height, no roll), not with terralod::pm::View.
//
// What is measured: for every triangle and every valid sample in the closed triangle (exact
// integer point-in-triangle tests, so a sample on a shared edge counts for each triangle), the
// vertical segment at the sample's world (x, y) from the triangle's height there (barycentric
// interpolation, long double) to the sample's height is transformed to clip space with the
// camera matrices, clipped against the view frustum (-w <= x, y, z <= w, which is the near and
// far planes and the image rectangle), and the pixel distance between the projected ends of
// the clipped part is its screen-space error. Segments entirely outside the frustum measure
// nothing, so only what is inside the frustum counts (a stricter test than counting whole
// triangles inside it: a segment of a triangle outside the frustum that pokes into it counts).
//
// Cost: O(sum of triangle bounding-box rows + covered samples) per check, about 40 ns per
// covered sample. Memory: none beyond the result.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/progressive_mesh.hpp"
#include "terralod/pm/view.hpp"

namespace terralod::test {

/// The camera's matrices (GLM, double precision) and the projection of vertical segments.
class ScreenProjector {
 public:
  explicit ScreenProjector(const pm::Camera& camera);
  /// Pixel length of the part inside the frustum of the vertical segment at world (x, y)
  /// between heights z0 and z1 (either order); 0 when no part is inside.
  double vertical_segment_px(double x, double y, double z0, double z1) const;
  /// Pixel coordinates of a world point; false when it is not in front of the camera.
  bool project(double x, double y, double z, double& px, double& py) const;
  /// Clip-space frustum test of a world point (borders included).
  bool inside(double x, double y, double z) const;
  const pm::Camera& camera() const { return cam_; }
  const std::array<double, 16>& view_projection() const { return m_; }  ///< column-major

 private:
  pm::Camera cam_;
  std::array<double, 16> m_{};  // projection * view, column-major
};

struct ScreenCheck {
  double max_error_px = 0.0;  ///< largest projected error of any visible segment
  int worst_col = -1, worst_row = -1;
  std::size_t worst_triangle = 0;
  double worst_error_m = 0.0;         ///< vertical length of the worst segment, metres
  std::size_t samples_measured = 0;   ///< (triangle, sample) pairs evaluated
  std::size_t segments_visible = 0;   ///< of those, with a part inside the frustum
  std::size_t triangles_visible = 0;  ///< triangles with at least one visible segment
  double max_error_m = 0.0;           ///< largest vertical error of a visible segment, metres
  std::string describe() const;
};

/// Measures the projected error of every visible sample segment of `mesh` (vertices are
/// samples of `hf`, heights the samples' own).
ScreenCheck check_screen_error(const pm::Heightfield& hf, const pm::TriangleMesh& mesh,
                               const ScreenProjector& camera);

/// Height of a displayed surface at every valid sample: the mesh has vertex positions
/// (col, row, z) in index space (geomorphing vertices are off the grid) and triangles; each
/// sample gets the height of a non-degenerate triangle containing it (closed test), NaN if none.
/// Also counts the triangles whose plan-view orientation is negative (flipped).
struct SurfaceSamples {
  std::vector<double> height;  ///< per sample, NaN where no triangle covers it
  std::size_t flipped = 0, degenerate = 0;
};
SurfaceSamples surface_at_samples(const pm::Heightfield& hf,
                                  const std::vector<std::array<double, 3>>& positions,
                                  const std::vector<std::array<std::uint32_t, 3>>& triangles);

/// Inverse of hf.transform: world (x, y) to index space (col, row).
std::array<double, 2> world_to_index(const pm::Heightfield& hf, double x, double y);

// --- Scenes for view-dependent tests -----------------------------------------------------------

/// Bilinear height of the heightfield under world (x, y), clamped to the grid.
double ground_height(const pm::Heightfield& hf, double x, double y);

/// A random camera over or near the terrain: position uniform over the extent grown by a
/// quarter on every side, height above ground log-uniform in [2 m, 2 x extent], yaw uniform,
/// pitch in [-90, 15], fovy in [30, 90], viewport 1280 x 720 or 640 x 480, near 1 m.
pm::Camera random_pose(const pm::Heightfield& hf, std::mt19937_64& rng);

/// A random ground scale (pm/view.hpp): singular values uniform in [0.8, 1.25] along a direction
/// uniform in [0, 180) degrees (a map projection's are within a few per cent of 1).
pm::GroundScale random_ground_scale(std::mt19937_64& rng);

/// A scripted low flight: an ellipse inside the extent at `height_m` above the ground ahead,
/// looking along the path and down by `pitch_deg`, one pose per frame, 1280 x 720, fovy 60.
std::vector<pm::Camera> scripted_flight(const pm::Heightfield& hf, int frames, double height_m = 150.0,
                                        double pitch_deg = -15.0, double laps = 1.0);

/// A size x size crop (top-left sample col0, row0) of a 1201 x 1201 SRTM tile in
/// TERRALOD_DATA_DIR, in a north-up metric frame (66.09 m x 92.66 m for latitude 44.5), or
/// nothing when the file is absent.
std::optional<pm::Heightfield> read_hgt_crop(const std::string& name, int col0, int row0, int size);

}  // namespace terralod::test
