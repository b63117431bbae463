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

/// A fractal terrain of any size whose every sample is computed on its own, so that terrains
/// larger than memory are written strip by strip (blocks/dem_writer.hpp, `terralod testdem`):
/// value-noise fBm, octaves of wavelength 2^k samples from the first power of two at least half
/// the larger side down to 2 samples, amplitudes falling by `roughness` per octave, each
/// interpolated with the quintic smoothstep between hashed lattice values (SplitMix64: the same
/// numbers on every platform and in any order). Heights lie in [0, relief] (the fBm scaled by
/// its largest possible amplitude, so a crop is a crop of the larger terrain's heights only when
/// both have the same octaves) and are rounded to `height_quantum` when it is > 0.
///
/// Usage:
///   const terralod::pm::FractalField f({.width = 32769, .height = 32769, .seed = 7});
///   double z = f.at(col, row);   // any (col, row) in the grid, any order, any thread
///
/// Cost: about 4 hashes and one interpolation per octave per sample (15 octaves at 32769^2).
/// Errors: std::invalid_argument for a size below 1, spacing <= 0, relief < 0, roughness outside
/// (0, 1) or a negative height_quantum.
class FractalField {
 public:
  struct Options {
    std::int64_t width = 257, height = 257;
    std::uint64_t seed = 1;
    double spacing = 30.0;           ///< metres between samples, both axes
    double relief = 1200.0;          ///< metres between the lowest and highest possible height
    double roughness = 0.5;          ///< amplitude ratio between octaves
    double height_quantum = 0.0625;  ///< 1/16 m, exact in float; 0 keeps full precision
  };
  explicit FractalField(const Options& options);
  double at(std::int64_t col, std::int64_t row) const;
  const Options& options() const { return o_; }
  int octaves() const { return octaves_; }
  /// North-up, south-west sample at (0, 0), metres (as generate_terrain).
  GridTransform transform() const;

 private:
  Options o_;
  int octaves_ = 1;
  int top_shift_ = 1;  ///< log2 of the longest wavelength, samples
  double norm_ = 1.0;  ///< 1 / the sum of the octaves' amplitudes
};

}  // namespace terralod::pm
