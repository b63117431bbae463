// Private to the exporters: one tile's mesh as a glTF 2.0 binary (.glb) for 3D Tiles content.
//
// Layout: positions are the tile's decoded vertices (quantized_mesh.hpp: what a quantized-mesh
// client decodes) in Earth-centred, Earth-fixed coordinates, stored relative to the tile's
// bounding-sphere centre in glTF's Y-up axes (x, z, -y of ECEF; 3D Tiles turns glTF's Y-up back
// to Z-up), quantized with KHR_mesh_quantization: SHORT normalized (3 components, stride 8) with
// the node's uniform scale s and translation T; normals BYTE
// normalized (stride 4); indices UNSIGNED_SHORT (UNSIGNED_INT over 65535 vertices). One node,
// one mesh, one primitive (triangles), no material (clients draw their default). Triangles are in
// vertex-cache order and vertices in first-use order (meshoptimizer). `meshopt`: the three buffer
// views are also EXT_meshopt_compression encoded (attributes codec for positions and normals,
// triangle codec for indices, no filter) in buffer 0, and the uncompressed layout above is the
// extension's fallback buffer 1, which holds no data: the extension is required. Skirts: every
// edge vertex is repeated `skirt` metres lower and joined to its edge by triangles facing both
// ways, so where a client draws neighbours of different levels (REPLACE refinement) no crack
// shows between their edges (the vertex count includes the skirt's).
//
// Every tile of a level quantizes on one lattice: s is the level's `scale` (a power of two at
// least the largest distance of a vertex from its tile's centre) and T is the tile's rectangle
// centre (ECEF, height 0) rounded to a multiple of s / 32767, so a vertex that two neighbours
// share is stored at the same lattice point by both: no crack opens between them.
//
// Contract: tile as make_quantized_mesh returns it; normal(i) the unit ECEF normal of tile
// vertex i; offsets beyond `scale` are clamped (and show in `displacement`). `displacement` is the largest
// distance, metres, between a vertex as stored (after the 16-bit quantization) and the decoded vertex it
// stands for; `longest_edge` the longest triangle edge (ECEF chord, metres), from which the exporter bounds
// how far a flat triangle departs from the surface it interpolates.
#pragma once

#include <functional>
#include <string>

#include "terralod/blocks/quantized_mesh.hpp"

namespace terralod::blocks::detail {

struct GlbTile {
  std::string bytes;
  double displacement = 0;
  double longest_edge = 0;
};

GlbTile encode_tile_glb(const QuantizedMeshTile& tile, const GeoRect& rect,
                        const std::function<pm::Ecef(std::size_t)>& normal, double scale, double skirt,
                        bool meshopt, const std::string& path);

}  // namespace terralod::blocks::detail
