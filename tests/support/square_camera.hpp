// The camera the render tests look at their flat 64 m square [0, 64] x [0, 64] with: straight
// down from 32 m above its centre, a 90 degree field, 64 x 64 pixels. K = 32 px per unit tangent,
// so pixel (i, j) shows world (i + 0.5, 63.5 - j): one pixel per metre exactly.
#pragma once

#include "terralod/pm/view.hpp"

namespace terralod::test {

inline pm::Camera square_down_camera() {
  return pm::Camera{.x = 32.0,
                    .y = 32.0,
                    .z = 32.0,
                    .pitch_deg = -90.0,
                    .fovy_deg = 90.0,
                    .width_px = 64,
                    .height_px = 64,
                    .near_m = 1.0,
                    .far_m = 1000.0,
                    .ground = {}};
}

}  // namespace terralod::test
