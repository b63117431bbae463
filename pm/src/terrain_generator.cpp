// Deterministic diamond-square fractal terrain, cropped from the enclosing (2^k+1)^2 grid.
#include "terralod/pm/terrain_generator.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <stdexcept>
#include <vector>

namespace terralod::pm {
namespace {

// SplitMix64: a 64-bit integer hash, so every platform draws the same numbers.
std::uint64_t mix(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

// Uniform in [-1, 1), from the seed and the sample position only (order-independent).
double noise(std::uint64_t seed, int i, int j) {
  std::uint64_t h = mix(seed ^ mix((std::uint64_t(std::uint32_t(i)) << 32) | std::uint32_t(j)));
  return double(h >> 11) * (2.0 / 9007199254740992.0) - 1.0;
}

}  // namespace

Heightfield generate_terrain(const TerrainOptions& o) {
  if (o.width < 1 || o.height < 1)
    throw std::invalid_argument("generate_terrain: width and height must be >= 1");
  if (!(o.spacing > 0.0)) throw std::invalid_argument("generate_terrain: spacing must be > 0");
  if (!(o.relief >= 0.0)) throw std::invalid_argument("generate_terrain: relief must be >= 0");
  if (!(o.height_quantum >= 0.0))
    throw std::invalid_argument("generate_terrain: height_quantum must be >= 0");
  if (!(o.roughness > 0.0 && o.roughness < 1.0))
    throw std::invalid_argument("generate_terrain: roughness must be in (0,1)");

  int n = 1;
  while (n + 1 < std::max(o.width, o.height)) n *= 2;
  const int size = n + 1;
  std::vector<double> g(std::size_t(size) * size, 0.0);
  auto at = [&](int i, int j) -> double& { return g[std::size_t(j) * size + i]; };

  double amp = 1.0;
  for (int step = n; step >= 2; step /= 2) {
    const int h = step / 2;
    // Diamond: centres of squares.
    for (int j = h; j < size; j += step)
      for (int i = h; i < size; i += step)
        at(i, j) = 0.25 * (at(i - h, j - h) + at(i + h, j - h) + at(i - h, j + h) + at(i + h, j + h)) +
                   amp * noise(o.seed, i, j);
    // Square: edge midpoints, averaging the neighbours that exist.
    for (int j = 0; j < size; j += h)
      for (int i = ((j / h) % 2 == 0) ? h : 0; i < size; i += step) {
        double sum = 0.0;
        int count = 0;
        if (i - h >= 0) sum += at(i - h, j), ++count;
        if (i + h < size) sum += at(i + h, j), ++count;
        if (j - h >= 0) sum += at(i, j - h), ++count;
        if (j + h < size) sum += at(i, j + h), ++count;
        at(i, j) = sum / count + amp * noise(o.seed, i, j);
      }
    amp *= o.roughness;
  }

  Heightfield hf(o.width, o.height);
  double lo = 1e300, hi = -1e300;
  for (int j = 0; j < o.height; ++j)
    for (int i = 0; i < o.width; ++i) lo = std::min(lo, at(i, j)), hi = std::max(hi, at(i, j));
  const double scale = hi > lo ? o.relief / (hi - lo) : 0.0;
  for (int j = 0; j < o.height; ++j)
    for (int i = 0; i < o.width; ++i) {
      double z = (at(i, j) - lo) * scale;
      if (o.quantize_to_metres)
        z = std::floor(z + 0.5);
      else if (o.height_quantum > 0.0)
        z = std::floor(z / o.height_quantum + 0.5) * o.height_quantum;
      hf.at(i, j) = z;
    }
  hf.transform = GridTransform::north_up(0.0, (o.height - 1) * o.spacing, o.spacing, o.spacing);
  hf.source = "generated terrain (diamond-square, seed " + std::to_string(o.seed) + ")";
  hf.frame = "generated: south-west sample at (0,0), metres";
  return hf;
}

FractalField::FractalField(const Options& o) : o_(o) {
  if (o.width < 1 || o.height < 1) throw std::invalid_argument("FractalField: width and height must be >= 1");
  if (!(o.spacing > 0.0)) throw std::invalid_argument("FractalField: spacing must be > 0");
  if (!(o.relief >= 0.0)) throw std::invalid_argument("FractalField: relief must be >= 0");
  if (!(o.roughness > 0.0 && o.roughness < 1.0))
    throw std::invalid_argument("FractalField: roughness must be in (0,1)");
  if (!(o.height_quantum >= 0.0)) throw std::invalid_argument("FractalField: height_quantum must be >= 0");
  top_shift_ = 1;
  while ((std::int64_t(1) << top_shift_) * 2 < std::max(o.width, o.height) && top_shift_ < 40) ++top_shift_;
  octaves_ = top_shift_;  // wavelengths 2^top .. 2^1
  double sum = 0.0, amp = 1.0;
  for (int k = 0; k < octaves_; ++k, amp *= o.roughness) sum += amp;
  norm_ = 1.0 / sum;
}

double FractalField::at(std::int64_t col, std::int64_t row) const {
  double z = 0.0, amp = 1.0;
  for (int k = 0; k < octaves_; ++k, amp *= o_.roughness) {
    const int shift = top_shift_ - k;
    const std::int64_t i = col >> shift, j = row >> shift;
    const double size = double(std::int64_t(1) << shift);
    const double fx = double(col - (i << shift)) / size, fy = double(row - (j << shift)) / size;
    const double sx = fx * fx * fx * (fx * (fx * 6.0 - 15.0) + 10.0),
                 sy = fy * fy * fy * (fy * (fy * 6.0 - 15.0) + 10.0);
    const std::uint64_t seed = mix(o_.seed + std::uint64_t(k));
    const double a = noise(seed, int(i), int(j)), b = noise(seed, int(i + 1), int(j)),
                 c = noise(seed, int(i), int(j + 1)), d = noise(seed, int(i + 1), int(j + 1));
    z += amp * ((a + (b - a) * sx) + ((c + (d - c) * sx) - (a + (b - a) * sx)) * sy);
  }
  double h = 0.5 * o_.relief * (1.0 + z * norm_);
  if (o_.height_quantum > 0.0) h = std::floor(h / o_.height_quantum + 0.5) * o_.height_quantum;
  return h;
}

GridTransform FractalField::transform() const {
  return GridTransform::north_up(0.0, double(o_.height - 1) * o_.spacing, o_.spacing, o_.spacing);
}

}  // namespace terralod::pm
