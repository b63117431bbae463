// The exact error of node surfaces and the z range of a node's domain, streamed window by window
// from a DemSource, so that a node whose domain is larger than memory (the root: the whole DEM)
// gets the numbers surface_error and the tree builder's domain box give over the whole
// heightfield, bit for bit (issue 17). Private to blocks.
//
// Usage:
//   const NodeSurface* s[] = {&grid_surface, &tin_surface};
//   const detail::SurfaceScan r =
//       detail::scan_surfaces(*src, domain, s, pm::ErrorMetric::Continuous, /*window_samples=*/257 * 257);
//   // r.errors[1] == surface_error(hf, tin_surface, Continuous); r.zlo, r.zhi: the domain's z range
//
// Contract:
//   src           the DEM; every window is read once (read() is called concurrently when threads > 1).
//   domain        inclusive, inside src.grid(); the surfaces' triangles lie in it (points are whole-grid
//                 samples with z == the sample's height, as NodeSurface promises for every strategy).
//   surfaces      any number (the 'auto' strategy measures four at once); errors[i] is surfaces[i]'s.
//   window_samples  >= 4: the most samples one read may hold. Windows are rectangles of about
//                 sqrt(window_samples) samples a side, overlapping their neighbours by one sample row
//                 and column.
//   threads       windows measured in parallel (pm::parallel_for: <= 0 = all cores); the results do
//                 not depend on it.
//   zlo, zhi      min and max of the domain's valid samples; 0, 0 when it has none.
// Memory: one window per thread plus the surfaces' triangles and one error per window and surface.
#pragma once

#include <cstddef>
#include <span>
#include <vector>

#include "terralod/blocks/approximation_tree.hpp"
#include "terralod/blocks/dem_source.hpp"
#include "terralod/blocks/sample_rect.hpp"
#include "terralod/pm/linf_error.hpp"

namespace terralod::blocks::detail {

struct SurfaceScan {
  std::vector<double> errors;  ///< errors[i]: surface_error of surfaces[i]
  double zlo = 0.0, zhi = 0.0;
};

SurfaceScan scan_surfaces(const DemSource& src, SampleRect domain,
                          std::span<const NodeSurface* const> surfaces, pm::ErrorMetric metric,
                          std::size_t window_samples, int threads = 1);

/// The windows scan_surfaces reads, in row-major order: they cover `domain`, each at most
/// window_samples (>= 4) samples, neighbours sharing one sample row or column.
std::vector<SampleRect> scan_windows(SampleRect domain, std::size_t window_samples);

}  // namespace terralod::blocks::detail
