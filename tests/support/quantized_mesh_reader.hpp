// Independent reader of quantized-mesh-1.0 tiles for the tests: written from the format's
// specification (github.com/CesiumGS/quantized-mesh), sharing no code with the encoder
// (blocks/quantized_mesh.hpp). It gunzips when the bytes start with the gzip magic, decodes
// the zig-zag deltas and the high-water-mark indices, and checks every length against the
// buffer; any inconsistency throws std::runtime_error saying what is wrong.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace terralod::test {

struct DecodedTile {
  double center[3] = {0, 0, 0};
  float min_height = 0, max_height = 0;
  double sphere[4] = {0, 0, 0, 0};
  double horizon[3] = {0, 0, 0};
  std::vector<int> u, v, h;                             // decoded values, 0..32767
  std::vector<std::array<std::uint32_t, 3>> triangles;  // decoded indices
  std::array<std::vector<std::uint32_t>, 4> edges;      // west, south, east, north
  std::vector<std::array<std::uint8_t, 2>> normals;     // extension 1 (empty when absent)
  std::string metadata;                                 // extension 4 (empty when absent)
  bool wide_indices = false;
};

DecodedTile decode_quantized_mesh_tile(std::span<const std::uint8_t> bytes);

/// Cesium's oct decoding of two bytes to a unit vector.
std::array<double, 3> oct_decode(std::uint8_t x, std::uint8_t y);

}  // namespace terralod::test
