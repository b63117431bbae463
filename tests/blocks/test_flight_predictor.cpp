// Tests of the flight-path predictor (blocks/flight_predictor.hpp) on exact motions: a straight
// line is extrapolated exactly, a circle is followed, a still camera predicts itself only. The
// prefetch it drives is tested through the runtime (test_terrain_runtime.cpp).
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "terralod/blocks/flight_predictor.hpp"

namespace tb = terralod::blocks;

TEST(FlightPredictor, StraightLineIsExtrapolatedExactly) {
  // 100 m/s east, 2 m/s up, sampled at 60 Hz: the prediction 2 s ahead is 200 m east, 4 m up.
  tb::FlightPredictor p;
  for (int f = 0; f <= 60; ++f) p.observe(f / 60.0, {1000 + 100.0 * f / 60, 50, 300 + 2.0 * f / 60});
  EXPECT_NEAR(p.velocity().x, 100, 1e-9);
  EXPECT_NEAR(p.velocity().y, 0, 1e-9);
  EXPECT_NEAR(p.turn_rate(), 0, 1e-9);
  const std::vector<tb::PredictedPoint> q = p.predict(2.0, 0.5);
  ASSERT_EQ(q.size(), 5u);  // dt = 0, 0.5, 1, 1.5, 2
  EXPECT_EQ(q[0].dt, 0.0);
  EXPECT_NEAR(q[4].position.x, 1100 + 200, 1e-6);
  EXPECT_NEAR(q[4].position.y, 50, 1e-6);
  EXPECT_NEAR(q[4].position.z, 302 + 4, 1e-6);
}

TEST(FlightPredictor, CircleIsFollowed) {
  // A circle of radius 1000 m at 0.2 rad/s (200 m/s), counter-clockwise in (x, y). The
  // half-window chords underestimate the speed by sin(x)/x (< 0.1 % here); a quarter turn
  // (7.85 s) ahead the prediction stays within 10 m of the circle.
  const double r = 1000, w = 0.2;
  tb::FlightPredictor p;
  double t = 0;
  for (int f = 0; f <= 120; ++f) {
    t = f / 60.0;
    p.observe(t, {r * std::cos(w * t), r * std::sin(w * t), 500});
  }
  EXPECT_NEAR(p.turn_rate(), w, 1e-6);
  const double ahead = std::numbers::pi / 2 / w;
  const std::vector<tb::PredictedPoint> q = p.predict(ahead, ahead);
  ASSERT_EQ(q.size(), 2u);
  const double te = t + ahead;
  EXPECT_NEAR(q[1].position.x, r * std::cos(w * te), 10);
  EXPECT_NEAR(q[1].position.y, r * std::sin(w * te), 10);
  // A still camera predicts itself only.
  tb::FlightPredictor still;
  still.observe(0, {1, 2, 3});
  still.observe(1, {1, 2, 3});
  EXPECT_EQ(still.predict(3, 0.5).size(), 1u);
}
