// Private to the PM builder (pm_builder.cpp): LInfError's measurements of spokes and triangles
// through small direct-mapped caches, since re-evaluating a vertex after one neighbour changed
// meets mostly the same spokes and triangles again.
//
// Both caches are keyed by sample index (the builder's vertex ids change when it compacts) and
// hold exact errors, or lower bounds from measurements that stopped at a cutoff; a value is the
// one LInfError returns, so the PM does not depend on hits and misses. Memory: 512 KiB of
// spokes (stays in L2) and 1.5 MiB of triangles.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <vector>

#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/linf_error.hpp"
#include "triangle_cache.hpp"

namespace terralod::pm::detail {
namespace {  // one translation unit (pm_builder.cpp): internal linkage, as when the code lived there

class CachedLInfError {
 public:
  /// The heightfield must outlive this object.
  CachedLInfError(const Heightfield& hf, ErrorMetric metric) : err_(hf, metric), width_(hf.width()) {}

  /// The measurements themselves, uncached.
  const LInfError& exact() const { return err_; }

  /// Empties the triangle cache. Only triangles of 256 cells and more pass through it, and they
  /// are few: 66k lookups (22k hits) in a whole N44W072 build, against 15 M measurements of
  /// smaller ones. 2^16 slots (1.5 MiB, cache-resident) hold them, on any grid; the 2^22 slots
  /// used before cost 96 MiB of page faults per builder for nothing.
  void reset() { triangles_.reset(16); }

  /// LInfError::segment(pa, pb, cutoff), where pa is the endpoint of the smaller vertex id (an
  /// order the builder's compaction keeps, so that a spoke is always measured the same way).
  double segment(GridPoint pa, GridPoint pb, double cutoff) {
    // A short segment crosses few grid lines: measuring it costs less than a cache miss.
    if (std::abs(pa.x - pb.x) + std::abs(pa.y - pb.y) <= kShortSpoke) return err_.segment(pa, pb, cutoff);
    const std::uint32_t a = sample_at(pa), b = sample_at(pb);
    SpokeSlot& s =
        spokes_[(std::uint64_t(a) * 0x9E3779B97F4A7C15ull ^ std::uint64_t(b) * 0xC2B2AE3D27D4EB4Full) >> 49];
    if (s.a == a && s.b == b) {
      if (s.value >= 0) return s.value;        // exact
      if (-s.value > cutoff) return -s.value;  // a lower bound above the cutoff
    }
    const double e = err_.segment(pa, pb, cutoff);
    s = SpokeSlot{a, b, e <= cutoff ? e : -e};  // lower bounds (> cutoff >= 0) stored negated
    return e;
  }

  /// LInfError::samples_in_triangle(pa, pb, pc, cutoff) of a counter-clockwise triangle; the
  /// large ones (256 cells and more) through the triangle cache.
  double samples_in_triangle(GridPoint pa, GridPoint pb, GridPoint pc, double cutoff) {
    const std::int64_t area2 = orient2d(pa, pb, pc);
    if (area2 < 512) return err_.samples_in_triangle(pa, pb, pc, cutoff);
    std::uint32_t s[3] = {sample_at(pa), sample_at(pb), sample_at(pc)};
    std::sort(s, s + 3);
    double value;
    bool exact;
    if (triangles_.find(s[0], s[1], s[2], value, exact) && (exact || value > cutoff)) return value;
    value = err_.samples_in_triangle(pa, pb, pc, cutoff);
    triangles_.store(s[0], s[1], s[2], value, value <= cutoff);
    return value;
  }

 private:
  std::uint32_t sample_at(GridPoint p) const {
    return std::uint32_t(p.y) * std::uint32_t(width_) + std::uint32_t(p.x);
  }

  LInfError err_;
  int width_;
  TriangleCache triangles_;
  struct SpokeSlot {
    std::uint32_t a = UINT32_MAX, b = 0;
    double value = 0;  // exact error when >= 0, else minus a lower bound
  };
  std::vector<SpokeSlot> spokes_ = std::vector<SpokeSlot>(1 << 15);  // 512 KiB: stays in L2
  static constexpr int kShortSpoke = 6;
};

}  // namespace
}  // namespace terralod::pm::detail
