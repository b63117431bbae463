// Deterministic fractal terrain generator for the default run, tests and benchmarks.
//
// Usage:
//   terralod::pm::TerrainOptions opt;      // defaults: 257 x 257, seed 1, 30 m spacing
//   opt.width = 513; opt.height = 513; opt.seed = 42;
//   terralod::pm::Heightfield hf = terralod::pm::generate_terrain(opt);
//
// Contract: the same options give bit-identical samples on every platform that has IEEE
// doubles (the generator uses only + - * / and a 64-bit integer hash, no libm calls on
// the sample path). width, height >= 1; spacing > 0; relief >= 0 metres.
// Memory: 8 bytes per sample (the output) plus one scratch grid of the same size.
#pragma once

#include <cstdint>

#include "terralod/pm/heightfield.hpp"

namespace terralod::pm {

struct TerrainOptions {
  int width = 257;
  int height = 257;
  std::uint64_t seed = 1;
  double spacing = 30.0;            ///< metres between samples, both axes
  double relief = 1200.0;           ///< approximate peak-to-valley height, metres
  double roughness = 0.55;          ///< amplitude ratio between octaves, 0 < roughness < 1
  bool quantize_to_metres = false;  ///< round heights to whole metres, like SRTM
  /// Round heights to multiples of this (metres, > 0), like a DEM's vertical resolution;
  /// 0 keeps full double precision. quantize_to_metres takes precedence.
  double height_quantum = 0.0;
};

/// Fractal (diamond-square on the enclosing 2^k+1 grid, cropped) terrain; x0 = y0 = 0, north-up.
Heightfield generate_terrain(const TerrainOptions& options = {});

}  // namespace terralod::pm
