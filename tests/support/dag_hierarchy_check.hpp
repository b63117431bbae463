// The hierarchy invariants of a collapse DAG (the runtime's vertex hierarchy, collapse_dag.hpp),
// checked independently of how the DAG computed them: the saturated error of every collapse is
// its own error or its predecessors' largest (or that of a leaf face it removes, when the DAG
// skips the PM's first collapses), never below a predecessor's; every volume holds
// its predecessors' volumes (Fig. 4's nesting, boxes or spheres) and, optionally, the faces the
// collapse creates extruded by its error (clipped to the height range for boxes); corners never
// collapse and border vertices collapse only along their own border line.
//
// Usage:
//   const std::string why = terralod::test::dag_hierarchy_violation(dag);
//   EXPECT_EQ(why, "");   // empty: every invariant holds; otherwise the first violation
//
// Header-only so that the fuzz harness (which links terralod::pm only) uses the same checks.
// Cost: O(collapses + DAG edges + created faces).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>

#include "terralod/pm/collapse_dag.hpp"

namespace terralod::test {

struct DagCheckOptions {
  /// Also check that each collapse's volume holds its created faces extruded by its error
  /// (skipped by the fuzzer, whose absurd coordinates may overflow to infinity).
  bool created_faces_inside = true;
  /// Also check the builder's rules (corners stay, border vertices move along their border),
  /// which a decoded file need not follow to replay (skipped by the fuzzer).
  bool builder_rules = true;
};

inline std::string dag_hierarchy_violation(const pm::CollapseDag& dag, const DagCheckOptions& o = {}) {
  const pm::Heightfield& hf = dag.heightfield();
  const auto W = std::uint32_t(hf.width()), H = std::uint32_t(hf.height());
  const bool boxes = dag.volume_kind() == pm::VolumeKind::Box;
  double zlo = 1e300, zhi = -1e300;
  for (std::size_t i = 0; i < hf.size(); ++i)
    if (hf.valid(i)) zlo = std::min(zlo, hf[i]), zhi = std::max(zhi, hf[i]);
  const auto at = [](std::uint32_t c, const std::string& what) {
    return "collapse " + std::to_string(c) + ": " + what;
  };
  const auto in_box = [](const pm::Box& b, double x, double y, double zl, double zh) {
    return b.lo.x <= x && x <= b.hi.x && b.lo.y <= y && y <= b.hi.y && b.lo.z <= zl && zh <= b.hi.z;
  };
  for (std::uint32_t c = 0; c < dag.collapse_count(); ++c) {
    const pm::Collapse& k = dag.collapse(c);
    // Corners stay; border vertices move along their own border line.
    const std::uint32_t uc = k.u % W, ur = k.u / W, wc = k.w % W, wr = k.w / W;
    const bool on_column = uc == 0 || uc == W - 1, on_row = ur == 0 || ur == H - 1;
    if (o.builder_rules && on_column && on_row) return at(c, "a grid corner collapses");
    if (o.builder_rules && on_column && wc != uc) return at(c, "a border vertex leaves its column");
    if (o.builder_rules && on_row && wr != ur) return at(c, "a border vertex leaves its row");
    // Saturated error: max(own error, predecessors' saturated errors).
    const double sat = dag.saturated_error(c);
    if (!std::isfinite(sat) || !(sat >= 0.0)) return at(c, "saturated error not finite and >= 0");
    double want = k.error;
    for (std::uint32_t p : dag.preds(c)) {
      if (p >= c) return at(c, "a predecessor that comes later in the build");
      want = std::max(want, dag.saturated_error(p));
    }
    for (std::uint32_t f : dag.removed_faces(c))
      if (dag.creator(f) == pm::CollapseDag::kNone) want = std::max(want, dag.leaf_error(f));
    if (sat != want) return at(c, "saturated error " + std::to_string(sat) + " != " + std::to_string(want));
    // Volumes nest along the DAG.
    for (std::uint32_t p : dag.preds(c)) {
      if (boxes) {
        const pm::Box &b = dag.box(c), &q = dag.box(p);
        if (!in_box(b, q.lo.x, q.lo.y, q.lo.z, q.lo.z) || !in_box(b, q.hi.x, q.hi.y, q.hi.z, q.hi.z))
          return at(c, "box does not hold predecessor " + std::to_string(p) + "'s");
      } else {
        const pm::Sphere &s = dag.sphere(c), &q = dag.sphere(p);
        const double dx = q.center.x - s.center.x, dy = q.center.y - s.center.y, dz = q.center.z - s.center.z;
        if (std::isnan(s.radius) || !(std::sqrt(dx * dx + dy * dy + dz * dz) + q.radius <= s.radius))
          return at(c, "sphere does not hold predecessor " + std::to_string(p) + "'s");
      }
    }
    if (!o.created_faces_inside) continue;
    // Each created face, extruded by +-error, lies inside the volume.
    const auto [f0, f1] = dag.created_faces(c);
    for (std::uint32_t f = f0; f < f1; ++f)
      for (std::uint32_t s : dag.face(f)) {
        const pm::Vec3 q = dag.position(s);
        if (boxes) {
          if (!in_box(dag.box(c), q.x, q.y, std::max(q.z - k.error, zlo), std::min(q.z + k.error, zhi)))
            return at(c, "box does not hold created face " + std::to_string(f) + " extruded by its error");
        } else {
          const pm::Sphere& sp = dag.sphere(c);
          const double dx = q.x - sp.center.x, dy = q.y - sp.center.y,
                       dz = std::abs(q.z - sp.center.z) + k.error;
          if (!(std::sqrt(dx * dx + dy * dy + dz * dz) <= sp.radius))
            return at(c, "sphere does not hold created face " + std::to_string(f) + " extruded by its error");
        }
      }
  }
  return {};
}

}  // namespace terralod::test
