// glTF 2.0 encoding of a triangle mesh (the .glb and .gltf forms of write_mesh, mesh_io.hpp).
//
// Usage (mesh_io.cpp):
//   const std::string bytes = detail::encode_gltf(mesh, /*binary=*/true, {"terralod mesh"}, path);
//   write_file_atomically(path, bytes);
//
// Contract:
//   mesh      positions in our world frame (x east, y north, z up; metres in Units::World) and
//             triangles CCW seen from outside (from +z for a terrain); every index < the vertex
//             count (write_mesh checks it), at most 2^31 vertices.
//   binary    true: a .glb file; false: a .gltf JSON text with the buffer as a data URI.
//   comments  kept as asset.extras.comments (JSON strings).
//   path      the file's name, for messages only.
//   returns   the whole file; std::runtime_error naming `path` for a position that is not finite
//             (JSON has no NaN) or a buffer over glTF's uint32 lengths (4 GiB, about 150 million
//             vertices). Memory: about 28 bytes per vertex and 12 per triangle, twice (the
//             buffer and the file), plus 4/3 of that for .gltf's base64.
//
// Layout (glTF 2.0, https://registry.khronos.org/glTF/specs/2.0/glTF-2.0.html). The format has
// its own version ("asset.version": "2.0") and no checksum; readers check the lengths below.
//
//   Frame: gltf = (x, z, -y) for every position and normal: Y up, right-handed, a rotation of
//   ours (determinant +1), so a triangle CCW seen from +z is CCW seen from +Y (glTF's front
//   faces are CCW). centre = the midpoint of the bounding box in glTF axes (doubles); the
//   stored positions are float(p - centre) and nodes[0].translation = centre.
//
//   Buffer 0 (N vertices, T triangles), little-endian, every bufferView at a multiple of 4:
//     offset 0       N x 3 float32   POSITION, relative to the centre
//     offset 12 N    N x 3 float32   NORMAL, unit length: the sum of the cross products of the
//                                    triangles around the vertex (area-weighted), normalised;
//                                    (0, 1, 0) where that sum is zero (unused vertex, degenerate
//                                    triangles only)
//     offset 24 N    3 T x uint16    indices when N <= 65535 (65535 is never an index: glTF
//                    or uint32       reserves each type's largest value), else uint32
//     byteLength = 24 N + 3 T x (2 or 4) (not padded; the GLB chunk is).
//
//   JSON: asset {version "2.0", generator "terralod", extras {comments}}; scene 0 = [node 0];
//   node 0 {mesh 0, translation centre}; mesh 0 = one primitive, mode 4 (triangles),
//   attributes {POSITION 0, NORMAL 1}, indices 2; accessors 0/1 FLOAT (5126) VEC3 with min/max
//   on accessor 0 (exact: the stored floats' own extremes, written as the double of each float),
//   accessor 2 UNSIGNED_SHORT (5123) or UNSIGNED_INT (5125) SCALAR, count 3 T; bufferViews 0, 1
//   target ARRAY_BUFFER (34962), 2 target ELEMENT_ARRAY_BUFFER (34963); accessor byteOffset 0.
//   A mesh with no triangles (glTF has no empty primitive) is a scene of node 0 without a mesh:
//   no meshes, accessors, bufferViews or buffers.
//
//   .glb: a 12-byte header: uint32 magic 0x46546C67 ("glTF"), uint32 version 2, uint32 total
//   length of the file; chunk 0: uint32 length, uint32 type 0x4E4F534A ("JSON"), the JSON text
//   padded with spaces (0x20) to a multiple of 4; chunk 1 (absent without triangles): uint32
//   length, uint32 type 0x004E4942 ("BIN\0"), the buffer padded with zeros to a multiple of 4.
//   buffers[0] has byteLength and no uri.
//   .gltf: the JSON text alone; buffers[0].uri = "data:application/octet-stream;base64,..."
//   (RFC 4648 alphabet with '=' padding).
#pragma once

#include <string>
#include <vector>

#include "terralod/pm/mesh_io.hpp"

namespace terralod::pm::detail {

std::string encode_gltf(const TriangleMeshData& mesh, bool binary, const std::vector<std::string>& comments,
                        const std::string& path);

}  // namespace terralod::pm::detail
