// Triangle mesh files: writers for extracted meshes (binary PLY, OBJ, glTF 2.0 .glb / .gltf) and
// readers for TINs made elsewhere (PLY in all three encodings, Wavefront OBJ).
//
// Usage:
//   terralod::pm::TriangleMesh m = pm.extract(/*max_error=*/2.0);
//   terralod::pm::write_mesh(m, pm.heightfield(), "terrain.ply", terralod::pm::Units::World);
//   terralod::pm::write_mesh(m, pm.heightfield(), "terrain.obj", terralod::pm::Units::Samples);
//   terralod::pm::write_mesh(m, pm.heightfield(), "terrain.glb", terralod::pm::Units::World);
//   terralod::pm::TriangleMeshData back = terralod::pm::read_mesh("terrain.ply");  // or .obj
//
// Contract (writing):
//   - The format comes from the extension, case-insensitive (mesh_format_of): ".ply" = PLY 1.0
//     binary_little_endian with `element vertex N` (property double x, y, z) and `element face
//     M` (property list uchar int vertex_indices); ".obj" = Wavefront OBJ text, "v x y z" with
//     the shortest decimal that reads back to the same double, "f a b c" (1-based); ".glb" =
//     binary glTF 2.0; ".gltf" = glTF 2.0 JSON with the buffer inline as a base64 data URI (one
//     file, so the write stays atomic; no sidecar .bin). Both glTF forms are laid out in
//     pm/src/gltf_writer.hpp: one mesh, one triangle primitive with float POSITION, area-weighted
//     unit NORMAL and uint16 (< 65535 vertices) or uint32 indices; axes mapped to glTF's Y-up
//     frame as gltf = (x, z, -y), a rotation, so faces stay CCW seen from outside; positions
//     stored as floats relative to the bounding-box centre, which is the node's `translation`
//     (JSON doubles), so large world coordinates (UTM, ECEF) keep float precision relative to
//     the mesh's own extent (about 1 mm across 20 km). Any other extension: std::runtime_error
//     naming the path.
//   - Units::Samples: x = column, y = row (row 0 = the file's first row), z = height in metres;
//     triangles keep the mesh's winding (CCW in (col,row)).
//     Units::World: (x, y) = hf.transform.to_world(col, row) in metres, z = height; when
//     hf.transform.determinant() < 0 (north-up rasters) the winding is flipped, so that faces
//     are CCW seen from above (+z) in the world frame (+Y in glTF).
//   - Vertex order is mesh.vertices' order; triangle indices refer to it.
//   - The file is written to path + ".tmp" and renamed onto path; on failure nothing is left
//     at path and std::runtime_error names the file and the reason.
//
// Contract (reading, for TINs from other tools):
//   - read_mesh(path) reads ".ply" (read_ply) or ".obj" (read_obj) by extension, case-insensitive;
//     any other extension: std::runtime_error naming the path.
//   - read_ply reads PLY 1.0 in `format ascii`, `binary_little_endian` and `binary_big_endian`:
//     vertex properties of any scalar type (x, y, z required, others skipped), one face list
//     property (vertex_indices or vertex_index) with an integer count and integer indices,
//     triangles only; other properties and elements are skipped (binary: only if they have no
//     lists; ascii: any).
//   - read_obj reads "v x y z" lines (numbers after z, a w or an r g b colour, are ignored) and
//     "f" lines whose corners are a, a/b, a/b/c or a//c with positive (1-based) or negative
//     (relative: -1 = the last v so far) indices; polygons of n > 3 corners become the fan
//     (0, i, i+1), i = 1..n-2; '#' comments, blank lines and every other statement (vt, vn, o,
//     g, s, usemtl, mtllib, l, p, ...) are ignored. A file without any "v" line is an error
//     (not an OBJ mesh; a PLY or anything else renamed .obj would otherwise read as empty).
//   - Errors are std::runtime_error "<path>: ..." naming the line (ascii PLY, OBJ) or the
//     element and record (binary PLY) that is wrong: truncation, a bad number, an index out of
//     range. Counts are checked against the file size before anything is allocated (an ascii
//     PLY value takes at least 2 bytes with its separator, a binary record its fixed size; OBJ
//     has no counts, its arrays grow with its lines). Only regular files are opened.
//     Memory: the file plus the result.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/progressive_mesh.hpp"

namespace terralod::pm {

enum class Units : std::uint8_t {
  Samples,  ///< x = column, y = row, z = height
  World,    ///< x, y from the heightfield's GridTransform (metres), z = height
};

/// The mesh file formats, named by their extensions.
enum class MeshFormat : std::uint8_t {
  Ply,   ///< ".ply": written binary little-endian; read in all three PLY encodings
  Obj,   ///< ".obj": Wavefront OBJ text
  Glb,   ///< ".glb": binary glTF 2.0 (written only)
  Gltf,  ///< ".gltf": glTF 2.0 JSON with an embedded base64 buffer (written only)
};

/// The format `path`'s extension names (case-insensitive), or std::nullopt for any other.
std::optional<MeshFormat> mesh_format_of(const std::string& path);

/// The extensions write_mesh accepts, for messages.
inline constexpr const char* kMeshWriteExtensions = ".ply, .obj, .glb or .gltf";
/// The extensions read_mesh accepts, for messages.
inline constexpr const char* kMeshReadExtensions = ".ply or .obj";

/// A triangle mesh with explicit positions, as read from a file.
struct TriangleMeshData {
  std::vector<std::array<double, 3>> positions;
  std::vector<std::array<std::uint32_t, 3>> triangles;
};

/// Positions and triangles of `mesh` in the given units (the data write_mesh writes).
TriangleMeshData mesh_positions(const TriangleMesh& mesh, const Heightfield& hf, Units units);

/// Writes `mesh` (whose vertices are samples of `hf`) as .ply, .obj, .glb or .gltf, chosen by extension.
void write_mesh(const TriangleMesh& mesh, const Heightfield& hf, const std::string& path, Units units);

/// Writes explicit positions and triangles as .ply, .obj, .glb or .gltf, chosen by extension.
void write_mesh(const TriangleMeshData& mesh, const std::string& path);

/// Reads a .ply or .obj file, chosen by extension (see the contract above).
TriangleMeshData read_mesh(const std::string& path);

/// Reads a PLY file: ascii, binary little-endian or binary big-endian (see the contract above).
TriangleMeshData read_ply(const std::string& path);

/// Reads a Wavefront OBJ file's vertices and faces, fan-triangulated (see the contract above).
TriangleMeshData read_obj(const std::string& path);

}  // namespace terralod::pm
