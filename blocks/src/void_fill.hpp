// Harmonic (Laplace) void filling for height grids: the private interface used by dem_reader.cpp.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace terralod::blocks::detail {

/// What fill_voids_harmonic did.
struct VoidFillStats {
  std::size_t voids = 0;    ///< samples that were non-finite on entry (all are filled)
  std::size_t regions = 0;  ///< 4-connected void regions
  int iterations = 0;       ///< conjugate-gradient iterations
  double residual = 0;      ///< largest residual when they stopped (metres times neighbour count)
  int sweeps = 0;           ///< Gauss-Seidel sweeps after clipping
  double last_change = 0;   ///< largest change in the last sweep, metres
};

/// Replaces every non-finite sample of the width x height row-major grid `z` by the harmonic
/// interpolant of the valid samples (each filled sample = mean of its 4-neighbours inside the
/// grid). Every filled value lies within [min, max] of the valid samples 4-adjacent to its
/// 4-connected void region, exactly (bit for bit), however many sweeps ran.
/// Preconditions: z.size() == width * height, width * height < 2^32, at least one sample
/// finite, width >= 1, height >= 1.
VoidFillStats fill_voids_harmonic(std::vector<double>& z, int width, int height);

}  // namespace terralod::blocks::detail
