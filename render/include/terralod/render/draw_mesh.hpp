// DrawMesh: the plain data the renderer draws (float positions relative to a double origin,
// two heights per vertex for geomorphs, normals, triangles), and how to make one from a PM mesh.
//
// Usage:
//   terralod::pm::TriangleMesh m = pm.extract(/*max_error=*/2.0);
//   terralod::render::DrawMesh dm = terralod::render::make_draw_mesh(m, pm.heightfield());
//   // dm.origin = centre of the grid at mid height; dm.xyz relative to it, metres
//   dm.z_target = ...;              // optional: heights the vertices morph to (alpha = 1)
//   renderer.upload(dm);            // see terrain_renderer.hpp
//
// Contract of DrawMesh (checked by validate(), which upload() calls):
//   - origin: world position (x east, y north, z up, metres) that all vertex data is relative
//     to. Choose it near the mesh (the helper uses the grid centre) so that the floats keep
//     millimetre precision; meshes that must meet bit-exactly at seams share one origin.
//   - xyz: 3 floats per vertex, world position minus origin; z is the height at alpha = 0.
//   - z_target: empty, or 1 float per vertex: height (minus origin.z) at alpha = 1. A draw at
//     alpha shows z = (1-alpha) * xyz.z + alpha * z_target, exactly xyz.z at 0 and z_target at 1.
//   - normals: empty (the renderer then uses area-weighted normals of the triangles), or 3
//     floats per vertex, unit length, world frame, pointing up (+z component > 0).
//   - indices: 3 per triangle, each < vertex count; counter-clockwise seen from above (+z)
//     in the world frame (the renderer does not cull, so the winding only matters to users
//     that do).
//   - Every float is finite. The renderer copies what it needs: the DrawMesh may be freed
//     after upload().
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <glm/glm.hpp>
#include <optional>
#include <span>
#include <vector>

#include "terralod/blocks/drawn_mesh.hpp"
#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/mesh_io.hpp"
#include "terralod/pm/progressive_mesh.hpp"
#include "terralod/pm/view.hpp"

namespace terralod::render {

struct DrawMesh {
  glm::dvec3 origin{0.0, 0.0, 0.0};
  std::vector<float> xyz;
  std::vector<float> z_target;
  std::vector<float> normals;
  std::vector<std::uint32_t> indices;

  std::size_t vertex_count() const { return xyz.size() / 3; }
  std::size_t triangle_count() const { return indices.size() / 3; }
};

/// Throws std::invalid_argument naming the first problem (sizes, an index out of range, a
/// non-finite value). O(vertices + indices).
void validate(const DrawMesh& mesh);

/// Unit normal of the full-resolution surface at sample (col, row), world frame: central
/// differences of the heights (one-sided at the border and next to holes), mapped through
/// the heightfield's GridTransform. (0,0,1) where a sample has no valid neighbour on an axis.
glm::dvec3 heightfield_normal(const pm::Heightfield& hf, int col, int row);

struct DrawMeshOptions {
  /// Origin of the vertex data; default: the world position of the grid centre, at the
  /// middle of the valid heights.
  std::optional<glm::dvec3> origin;
  /// Normals from the full-resolution samples (heightfield_normal of the sample each vertex
  /// sits on). They do not change when the mesh coarsens or morphs, so the shading does not
  /// pop with the level of detail. false leaves DrawMesh::normals empty.
  bool sample_normals = true;
};

/// DrawMesh of a mesh whose vertices are samples of `hf` (as pm::ProgressiveMesh::extract
/// returns): world positions from hf.transform, heights from the samples, triangles flipped
/// when the transform mirrors (north-up rasters) so that they are CCW from above. z_target is
/// left empty (no geomorph). Asserts that the mesh's sample indices are inside the grid.
DrawMesh make_draw_mesh(const pm::TriangleMesh& mesh, const pm::Heightfield& hf,
                        const DrawMeshOptions& options = {});

/// The geometry of a displayed mesh (world positions, geomorphs included, and triangles CCW in
/// plan view at rest) into `out`, relative to `origin`: xyz = position - origin, triangles made
/// CCW from above (flip_winding for a mirroring grid transform, determinant < 0), z_target
/// cleared; normals are left to the caller. Reuses out's buffers. O(vertices + triangles).
void fill_draw_geometry(std::span<const pm::Vec3> positions,
                        std::span<const std::array<std::uint32_t, 3>> triangles, const glm::dvec3& origin,
                        bool flip_winding, DrawMesh& out);

/// The runtime's drawn mesh (blocks::TerrainRuntime::drawn_mesh(): world positions with the
/// displayed heights, geomorphs included) as a DrawMesh relative to `origin`: triangles made
/// CCW from above (flip_winding for a mirroring grid transform, determinant < 0), normals
/// area-weighted over the drawn triangles (pointing up; (0,0,1) where they cancel), no
/// z_target. Reuses out's buffers. O(vertices + triangles).
void fill_draw_mesh(const blocks::DrawnMesh& mesh, const glm::dvec3& origin, bool flip_winding,
                    DrawMesh& out);

/// The mesh in the world frame, as drawn at alpha = 0: positions origin + xyz (double) and its
/// triangles (for pm::write_mesh: --dump-mesh, --dump-meshes).
pm::TriangleMeshData world_mesh(const DrawMesh& mesh);

/// Area-weighted vertex normals of the triangles (using xyz, i.e. alpha = 0), 3 floats per
/// vertex, unit length; (0,0,1) for a vertex no triangle uses.
std::vector<float> triangle_normals(const DrawMesh& mesh);

}  // namespace terralod::render
