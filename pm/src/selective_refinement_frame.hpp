// Private to SelectiveRefinement (selective_refinement*.cpp): the view constants of one update,
// read by the view test, the screen-space bound and update().
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

#include "terralod/pm/selective_refinement.hpp"

namespace terralod::pm {

// View constants of one update.
struct SelectiveRefinement::Frame {
  const View* view = nullptr;
  const View* cull = nullptr;  // the view, or its frustum widened by cull_margin
  double kf = 0.0;             // K * vertical_factor / tau: ok when E * kf <= max(zmin, near)
  double kvf = 0.0;            // K * vertical_factor
  double near = 0.0;
  double fz = 0.0;  // |depth_gradient.z|: depth change per metre of height
  // depth(col, row, z) = d0 + dc col + dr row + dz z (the transform is affine).
  double d0 = 0.0, dc = 0.0, dr = 0.0, dz = 0.0, inv_w = 0.0;
  double floor = -1.0;  // face_bound_px skips the plane tests below this value
  std::uint32_t w = 0;
  std::size_t evaluated = 0;

  Frame(const View& v, const Heightfield& hf, double tau) : view(&v), cull(&v) {
    kvf = v.focal_px() * v.vertical_factor();
    kf = kvf / tau;
    near = v.camera().near_m;
    fz = std::abs(v.depth_gradient().z);
    const GridTransform& t = hf.transform;
    const Vec3& f = v.depth_gradient();
    d0 = (t.x0 - v.eye().x) * f.x + (t.y0 - v.eye().y) * f.y - v.eye().z * f.z;
    dc = t.xc * f.x + t.yc * f.y;
    dr = t.xr * f.x + t.yr * f.y;
    dz = f.z;
    w = std::uint32_t(hf.width());
    inv_w = 1.0 / double(hf.width());
    set_cull(v, hf);
  }
  // Coordinates relative to the packed records' origin (x0, y0, 0) of the transform.
  double pd0 = 0.0, pf[3] = {0, 0, 0};  // depth = pd0 + pf . p
  double pl[6][4] = {};                 // cull planes: n . p + d
  void set_cull(const View& c, const Heightfield& hf) {
    cull = &c;
    const Vec3 o{hf.transform.x0, hf.transform.y0, 0.0};
    const Vec3& f = view->depth_gradient();
    pf[0] = f.x, pf[1] = f.y, pf[2] = f.z;
    pd0 = dot(o, f) - dot(view->eye(), f);
    for (int k = 0; k < 6; ++k) {
      const Plane& q = c.planes()[std::size_t(k)];
      pl[k][0] = q.n.x, pl[k][1] = q.n.y, pl[k][2] = q.n.z, pl[k][3] = q.distance(o);
    }
  }
};

}  // namespace terralod::pm
