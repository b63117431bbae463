// Constant-speed coordinated-turn prediction of the viewpoint; see flight_predictor.hpp.
#include "terralod/blocks/flight_predictor.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>

namespace terralod::blocks {

void FlightPredictor::observe(double time_s, const pm::Vec3& eye) {
  assert(samples_.empty() || time_s >= samples_.back().t);
  if (!samples_.empty() && time_s == samples_.back().t) samples_.pop_back();
  samples_.push_back({time_s, eye});
  while (samples_.size() > 2 && samples_.front().t < time_s - opt_.window_s) samples_.pop_front();
}

void FlightPredictor::estimate(pm::Vec3& v, double& omega) const {
  v = {};
  omega = 0;
  const std::size_t n = samples_.size();
  if (n < 2) return;
  auto mean_v = [&](std::size_t a, std::size_t b) {
    const double dt = samples_[b].t - samples_[a].t;
    const pm::Vec3& p = samples_[a].p;
    const pm::Vec3& q = samples_[b].p;
    return dt > 0 ? pm::Vec3{(q.x - p.x) / dt, (q.y - p.y) / dt, (q.z - p.z) / dt} : pm::Vec3{};
  };
  if (n < 3) {
    v = mean_v(0, 1);
    return;
  }
  const std::size_t m = n / 2;
  const pm::Vec3 va = mean_v(0, m), vb = mean_v(m, n - 1);
  v = vb;
  const double sa = std::hypot(va.x, va.y), sb = std::hypot(vb.x, vb.y);
  const double ta = 0.5 * (samples_[0].t + samples_[m].t), tb = 0.5 * (samples_[m].t + samples_[n - 1].t);
  if (sa > 1e-6 && sb > 1e-6 && tb > ta) {
    double d = std::atan2(vb.y, vb.x) - std::atan2(va.y, va.x);
    while (d > M_PI) d -= 2 * M_PI;
    while (d <= -M_PI) d += 2 * M_PI;
    omega = std::clamp(d / (tb - ta), -opt_.max_turn_rate, opt_.max_turn_rate);
    // The chord's heading is the heading at tb: turn it on to the last sample's time.
    const double a = omega * (samples_[n - 1].t - tb), c = std::cos(a), s = std::sin(a);
    v = {c * vb.x - s * vb.y, s * vb.x + c * vb.y, vb.z};
  }
}

pm::Vec3 FlightPredictor::velocity() const {
  pm::Vec3 v;
  double w;
  estimate(v, w);
  return v;
}

double FlightPredictor::turn_rate() const {
  pm::Vec3 v;
  double w;
  estimate(v, w);
  return w;
}

std::vector<PredictedPoint> FlightPredictor::predict(double horizon_s, double step_s) const {
  assert(horizon_s >= 0 && step_s > 0);
  std::vector<PredictedPoint> out;
  if (samples_.empty()) return out;
  pm::Vec3 v;
  double w;
  estimate(v, w);
  const pm::Vec3 p = samples_.back().p;
  const double s = std::hypot(v.x, v.y), phi = std::atan2(v.y, v.x);
  for (int i = 0;; ++i) {
    const double dt = i * step_s;
    if (dt > horizon_s + 1e-12) break;
    PredictedPoint q;
    q.dt = dt;
    q.position = p;
    if (std::abs(w) < 1e-9) {
      q.position.x += v.x * dt;
      q.position.y += v.y * dt;
    } else {
      q.position.x += s / w * (std::sin(phi + w * dt) - std::sin(phi));
      q.position.y -= s / w * (std::cos(phi + w * dt) - std::cos(phi));
    }
    q.position.z += v.z * dt;
    out.push_back(q);
    if (s == 0 && v.z == 0) break;  // still: one point is enough
  }
  return out;
}

}  // namespace terralod::blocks
