#include <gtest/gtest.h>

#include "linksight/tracker/geometry.hpp"

namespace linksight {
namespace {

constexpr double kTol = 1e-12;

TEST(ComponentGeometry, DefaultsAreTheLinkOfThePaper) {
  const ComponentGeometry g;
  EXPECT_NO_THROW(g.validate());
  EXPECT_DOUBLE_EQ(g.ball_radius, 0.015);
  EXPECT_DOUBLE_EQ(g.pitch, 0.045);
  EXPECT_EQ(g.count, 11);
}

TEST(ComponentGeometry, SdfOfBallAndNeck) {
  const ComponentGeometry g;
  EXPECT_NEAR(g.sdf({0, 0, 0}), -g.ball_radius, kTol);                 // centre: deepest
  EXPECT_NEAR(g.sdf({0.015, 0, 0}), 0.0, kTol);                        // ball surface
  EXPECT_NEAR(g.sdf({0, 0, -0.020}), 0.005, kTol);                     // behind the ball
  EXPECT_NEAR(g.sdf({0, 0.010, 0.025}), 0.010 - g.neck_radius, kTol);  // beside the neck
  EXPECT_NEAR(g.sdf({0, 0, 0.040}), 0.040 - g.neck_length - g.neck_radius, kTol);  // past the cap
  EXPECT_LT(g.sdf({0, 0, 0.028}), 0.0);  // inside the neck
}

TEST(ComponentGeometry, ValidateNamesTheField) {
  auto message = [](ComponentGeometry g) {
    try {
      g.validate();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  ComponentGeometry g;
  g.ball_radius = -1;
  EXPECT_EQ(message(g), "geometry.ball_radius_m = -1: must be in [0.0001, 1]");
  g = {};
  g.neck_radius = 0.02;
  EXPECT_EQ(message(g), "geometry.neck_radius_m = 0.02: must be < ball_radius_m (0.015)");
  g = {};
  g.pitch = 0.01;
  EXPECT_EQ(message(g), "geometry.pitch_m = 0.01: must be > ball_radius_m (0.015)");
  g = {};
  g.count = 0;
  EXPECT_EQ(message(g), "geometry.count = 0: must be in [1, 100]");
}

}  // namespace
}  // namespace linksight
