// Writers for extracted triangle meshes (binary PLY, OBJ) and a reader for binary PLY.
//
// Usage:
//   terralod::pm::TriangleMesh m = pm.extract(/*max_error=*/2.0);
//   terralod::pm::write_mesh(m, pm.heightfield(), "terrain.ply", terralod::pm::Units::World);
//   terralod::pm::write_mesh(m, pm.heightfield(), "terrain.obj", terralod::pm::Units::Samples);
//   terralod::pm::TriangleMeshData back = terralod::pm::read_ply("terrain.ply");
//
// Contract:
//   - The format comes from the extension, case-insensitive: ".ply" = PLY 1.0
//     binary_little_endian with `element vertex N` (property double x, y, z) and `element face
//     M` (property list uchar int vertex_indices); ".obj" = Wavefront OBJ text, "v x y z" with
//     the shortest decimal that reads back to the same double, "f a b c" (1-based). Anything
//     else: std::runtime_error naming the path.
//   - Units::Samples: x = column, y = row (row 0 = the file's first row), z = height in metres;
//     triangles keep the mesh's winding (CCW in (col,row)).
//     Units::World: (x, y) = hf.transform.to_world(col, row) in metres, z = height; when
//     hf.transform.determinant() < 0 (north-up rasters) the winding is flipped, so that faces
//     are CCW seen from above (+z) in the world frame.
//   - Vertex order is mesh.vertices' order; triangle indices refer to it.
//   - The file is written to path + ".tmp" and renamed onto path; on failure nothing is left
//     at path and std::runtime_error names the file and the reason.
//   - read_ply reads binary little-endian PLY: vertex properties of any scalar type (x, y, z
//     required, others skipped), one face list property with a uchar/ushort/uint/int count and
//     int/uint indices, triangles only; other elements are skipped if they have no lists.
//     Errors (std::runtime_error) name the file; counts are checked against the file size
//     before anything is allocated. Memory: the file plus the result.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/progressive_mesh.hpp"

namespace terralod::pm {

enum class Units : std::uint8_t {
  Samples,  ///< x = column, y = row, z = height
  World,    ///< x, y from the heightfield's GridTransform (metres), z = height
};

/// A triangle mesh with explicit positions, as read from a file.
struct TriangleMeshData {
  std::vector<std::array<double, 3>> positions;
  std::vector<std::array<std::uint32_t, 3>> triangles;
};

/// Positions and triangles of `mesh` in the given units (the data write_mesh writes).
TriangleMeshData mesh_positions(const TriangleMesh& mesh, const Heightfield& hf, Units units);

/// Writes `mesh` (whose vertices are samples of `hf`) as .ply or .obj, chosen by extension.
void write_mesh(const TriangleMesh& mesh, const Heightfield& hf, const std::string& path, Units units);

/// Writes explicit positions and triangles as .ply or .obj, chosen by extension.
void write_mesh(const TriangleMeshData& mesh, const std::string& path);

/// Reads a binary little-endian PLY file (see the contract above).
TriangleMeshData read_ply(const std::string& path);

}  // namespace terralod::pm
