// Cesium's quantized-mesh-1.0 terrain tiles: the geographic TMS tiling CesiumJS expects, the
// tile encoding (header, zig-zag delta vertices, high-water-mark indices, edge lists, oct-encoded
// normals and metadata extensions), gzip, and the tileset's layer.json.
//
// Usage:
//   namespace tb = terralod::blocks;
//   const tb::TileId id{12, 2425, 2958};
//   const tb::GeoRect r = tb::tile_rect(id);                            // degrees
//   tb::QuantizedMeshTile t = tb::make_quantized_mesh(r, vertices, triangles, {.normals = true});
//   std::vector<std::uint8_t> bytes = tb::gzip(tb::encode_quantized_mesh(t));
//   // DIR/12/2425/2958.terrain = bytes;  DIR/layer.json = tb::layer_json(...)
//
// Format (github.com/CesiumGS/quantized-mesh, little-endian):
//   header (88 bytes): centre (3 f64, ECEF), minimum and maximum height (2 f32), bounding
//   sphere (4 f64, ECEF centre and radius), horizon occlusion point (3 f64, ellipsoid-scaled
//   ECEF); u32 vertex count n; u[n], v[n], height[n] as u16 zig-zag deltas of values 0..32767
//   (u west -> east, v south -> north, height min -> max); padding to 2 (or 4) bytes; u32
//   triangle count and 3 indices each, u16 (u32 when n > 65536), high-water-mark coded (every
//   index is at most one more than the largest before it); four edge lists (west, south, east,
//   north: u32 count, indices); extensions: u8 id, u32 length, data (1: oct-encoded normals, 2
//   bytes per vertex; 4: metadata, u32 length + JSON).
// Tiling (EPSG:4326, scheme tms): level z has 2^(z+1) x 2^z tiles of 180 / 2^z degrees, x from
// -180 eastwards, y from -90 northwards.
//
// Contract of make_quantized_mesh: vertices are (longitude, latitude, ellipsoidal height) inside
// the rectangle; triangles CCW seen from above (east = +u, north = +v), non-degenerate after
// quantization is the caller's concern. The tile's vertices are reordered by first use in the
// triangle list (which the index coding needs); header fields are computed from the quantized
// positions: centre = bounding-sphere centre; heights quantized over [min, max] of the vertices
// (so each height moves by at most (max - min) / 65534 m); horizon point from
// pm::horizon_occlusion_point with the sphere centre as direction; edge lists are the vertices
// with u = 0, v = 0, u = 32767, v = 32767, sorted along the edge; normals (when asked) are the
// area-weighted vertex normals in ECEF, oct-encoded to 2 bytes as CesiumJS decodes them.
// Memory: the tile and its encoding.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "terralod/pm/geodesy.hpp"

namespace terralod::blocks {

struct GeoRect {
  double west = 0, south = 0, east = 0, north = 0;  ///< degrees
  bool operator==(const GeoRect&) const = default;
};

struct TileId {
  int z = 0, x = 0, y = 0;
  bool operator==(const TileId&) const = default;
};

/// The rectangle of a tile of the geographic TMS tiling (see above).
GeoRect tile_rect(TileId id);
/// CesiumJS's maximum geometric error for level z of this tiling, metres:
/// 6378137 * 2 pi * 0.25 / (65 * 2) / 2^z (what it assumes when it picks tiles).
double level_max_geometric_error(int z);

struct QuantizedMeshTile {
  pm::Ecef center{};
  float min_height = 0, max_height = 0;
  pm::EcefSphere sphere;
  pm::Ecef horizon{};                                   ///< ellipsoid-scaled ECEF
  std::vector<std::uint16_t> u, v, h;                   ///< 0..32767 each
  std::vector<std::array<std::uint32_t, 3>> triangles;  ///< CCW in (u, v)
  std::array<std::vector<std::uint32_t>, 4> edges;      ///< west, south, east, north
  std::vector<std::array<std::uint8_t, 2>> normals;     ///< oct-encoded; empty = no extension
  std::string metadata;                                 ///< JSON; empty = no extension
};

struct QuantizedMeshOptions {
  bool normals = true;   ///< the oct-encoded normals extension
  std::string metadata;  ///< the metadata extension's JSON (empty = none)
  /// > 0: heights are quantized on the lattice of this step (metres, a power of two for exact
  /// floats): min_height = floor(lowest / step) * step and max_height = min_height + 32767 * step,
  /// so that one height gives the same decoded value in every tile that uses the same step
  /// (neighbouring tiles then share edge vertices exactly). std::invalid_argument when the
  /// vertices span more than 32766 steps. 0: quantized over the vertices' own [min, max].
  double height_step = 0;
  /// When set, the unit normal (ECEF) of input vertex i, instead of the area-weighted normals of
  /// the tile's triangles (a normal that depends on the position only matches across tiles).
  std::function<pm::Ecef(std::size_t)> normal = {};
};

QuantizedMeshTile make_quantized_mesh(const GeoRect& rect, std::span<const pm::Geodetic> vertices,
                                      std::span<const std::array<std::uint32_t, 3>> triangles,
                                      const QuantizedMeshOptions& options = {});

/// The tile's bytes (uncompressed; servers and files hold them gzipped).
std::vector<std::uint8_t> encode_quantized_mesh(const QuantizedMeshTile& tile);

/// Oct encoding of a unit vector into two bytes, as CesiumJS's AttributeCompression.octEncode,
/// and its decoding (octDecode), a unit vector within about 1 degree of the encoded one.
std::array<std::uint8_t, 2> oct_encode(const pm::Ecef& unit);
pm::Ecef oct_decode(std::array<std::uint8_t, 2> bytes);

/// Per-vertex unit normals of a triangle mesh: the sum of the cross products of the triangles
/// around each vertex (area-weighted), normalised; the ellipsoid's normal under the vertex
/// where that sum is zero (an unused vertex). Positions and normals in ECEF.
std::vector<pm::Ecef> area_weighted_normals(std::span<const pm::Ecef> positions,
                                            std::span<const std::array<std::uint32_t, 3>> triangles);

/// gzip (RFC 1952) of bytes, zlib level 6.
std::vector<std::uint8_t> gzip(std::span<const std::uint8_t> bytes);

/// Available tiles of one level as rectangles of tile indices (inclusive).
struct TileRange {
  int start_x = 0, start_y = 0, end_x = 0, end_y = 0;
};
/// layer.json (tilejson 2.1.0) for a quantized-mesh tileset in this tiling: `available[z]` lists
/// the level's ranges; bounds in degrees; extensions as listed; `extra_members`, when not empty,
/// is appended as further members of the top-level object (JSON text such as `"a": 1`).
std::string layer_json(const std::string& name, const GeoRect& bounds,
                       const std::vector<std::vector<TileRange>>& available,
                       const std::vector<std::string>& extensions, const std::string& extra_members = "");

}  // namespace terralod::blocks
