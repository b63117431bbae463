// Flight-path prediction from the recent motion of the viewpoint (position, velocity, turn
// rate), used to queue the blocks along the predicted path before they are needed.
//
// Usage:
//   terralod::blocks::FlightPredictor pred;                   // window 0.5 s
//   pred.observe(/*time_s=*/t, eye);                          // every frame
//   for (const terralod::blocks::PredictedPoint& p : pred.predict(/*horizon_s=*/3, /*step_s=*/0.25))
//     { /* region around p.position, needed p.dt seconds from now */ }
//
// Paper: seeds/view-dependent-pm-dynamic-loading.txt, section 1 (iii): "the flight path is
// predicted to pre-load the necessary blocks in advance". Model: a coordinated turn at
// constant speed. Over the samples of the last window_s seconds, velocity v is the mean
// velocity of the window's second half, the turn rate omega = (heading of the second half's
// mean velocity - heading of the first half's) / (time between the halves' midpoints),
// wrapped to (-pi, pi]; v is then turned by omega from the second half's midpoint to the last
// sample (a chord's heading is the path's heading at the chord's middle time for a circle);
// the vertical speed stays constant. The horizontal velocity then
// rotates at omega: p(t + dt) = p + integral of R(omega s) v ds (closed form), |omega| clamped
// to max_turn_rate. With fewer than two samples (or a still camera) it predicts the current
// position.
//
// Contract: observe() times must not decrease (assert); positions finite. horizon_s >= 0,
// step_s > 0. Memory: the samples of one window (a deque of 32-byte entries).
#pragma once

#include <deque>
#include <vector>

#include "terralod/pm/view.hpp"

namespace terralod::blocks {

struct PredictorOptions {
  double window_s = 0.5;       ///< history used for velocity and turn rate, seconds, > 0
  double max_turn_rate = 1.0;  ///< |omega| limit, radians per second, >= 0
  bool operator==(const PredictorOptions&) const = default;
};

struct PredictedPoint {
  double dt = 0;      ///< seconds ahead of the last observation
  pm::Vec3 position;  ///< predicted eye, world metres
};

class FlightPredictor {
 public:
  explicit FlightPredictor(const PredictorOptions& options = {}) : opt_(options) {}

  void observe(double time_s, const pm::Vec3& eye);
  void reset() { samples_.clear(); }

  /// Current estimate (metres per second, radians per second).
  pm::Vec3 velocity() const;
  double turn_rate() const;
  /// Predicted eye at dt = step, 2 step, ... <= horizon_s (the current position first, dt = 0).
  std::vector<PredictedPoint> predict(double horizon_s, double step_s) const;

 private:
  struct Sample {
    double t;
    pm::Vec3 p;
  };
  void estimate(pm::Vec3& v, double& omega) const;
  PredictorOptions opt_;
  std::deque<Sample> samples_;
};

}  // namespace terralod::blocks
