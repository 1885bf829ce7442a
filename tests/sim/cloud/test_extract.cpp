// Cloud extraction from rendered frames (sim/extract): truth segmentation with leakage,
// depth segmentation with plane removal.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <utility>

#include "linksight/sim/extract.hpp"
#include "test_support.hpp"

namespace linksight::sim {
namespace {

std::vector<Eigen::Isometry3d> straight_chain(const ComponentGeometry& g) {
  return test::straight_chain_frames(g);
}

// The chain 0.5 m in front of the camera over a table (top at z = 0.4) before a wall
// (y = 0.3).
struct TableScene {
  ComponentGeometry g;
  SensorParams p;
  std::vector<BackgroundObject> background;
  explicit TableScene(NoiseParams noise) {
    p.camera.X_WC = look_at({0.25, -0.5, 0.6}, {0.25, 0.0, 0.5});
    p.noise = noise;
    BackgroundObject table, wall;
    table.shape.half_extents = Eigen::Vector3d(1.0, 1.0, 0.01);
    table.X_WO.translation() = Eigen::Vector3d(0.25, 0.3, 0.39);
    wall.shape.half_extents = Eigen::Vector3d(1.0, 0.01, 1.0);
    wall.X_WO.translation() = Eigen::Vector3d(0.25, 0.31, 0.5);
    background = {table, wall};
  }
};

std::size_t link_pixels(const DepthFrame& f, int count) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < f.label.size(); ++i) n += f.label[i] < count && f.depth.data[i] > 0;
  return n;
}

// Distance of a camera-frame point to the chain's balls and necks [m].
double distance_to_chain(const Eigen::Vector3d& p_C, const Eigen::Isometry3d& X_WC,
                         const std::vector<Eigen::Isometry3d>& X_WK, const ComponentGeometry& g) {
  double best = 1e9;
  for (const Eigen::Isometry3d& X : X_WK) {
    const Eigen::Vector3d p_K = X.inverse() * (X_WC * p_C);
    const double s = std::clamp(p_K.z(), 0.0, g.neck_length);
    best = std::min({best, std::abs(p_K.norm() - g.ball_radius),
                     std::abs((p_K - Eigen::Vector3d(0, 0, s)).norm() - g.neck_radius)});
  }
  return best;
}

TEST(Extract, TruthKeepsExactlyTheLinkPixels) {
  TableScene s(NoiseParams::off());
  s.p.noise.quantize = true;
  Sensor sensor(s.p, s.g, {}, s.background);
  const auto X = straight_chain(s.g);
  const DepthFrame f = sensor.render(X, 0.0, 1, 0);
  const Cloud cloud = extract_cloud(f, s.p.camera.intrinsics, s.g.count, {}, 1, 0);
  ASSERT_EQ(cloud.size(), link_pixels(f, s.g.count));
  ASSERT_GT(cloud.size(), 1000u);
  // On the surface up to the quantization (half a depth unit in z, times 1/cos of the
  // ray's angle to the axis: at most 1.2 within the 68 x 54 degree view) and the 0.05 mm
  // of the sensor's own noise-free geometry.
  const double tol = 0.5 * s.p.camera.intrinsics.depth_scale * 1.2 + 0.05e-3;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Eigen::Vector3d p(cloud.xyz[3 * i], cloud.xyz[3 * i + 1], cloud.xyz[3 * i + 2]);
    ASSERT_LT(distance_to_chain(p, s.p.camera.X_WC, X, s.g), tol) << "point " << i;
  }
}

TEST(Extract, LeakageKeepsThatFractionOfTheSilhouetteBand) {
  TableScene s(NoiseParams::off());
  Sensor sensor(s.p, s.g, {}, s.background);
  const DepthFrame f = sensor.render(straight_chain(s.g), 0.0, 1, 0);
  ExtractParams all;
  all.leakage = 1.0;
  all.leakage_px = 2;
  const std::size_t link = link_pixels(f, s.g.count);
  const std::size_t band = extract_cloud(f, s.p.camera.intrinsics, s.g.count, all, 1, 0).size() - link;
  ASSERT_GT(band, 500u);
  ExtractParams half = all;
  half.leakage = 0.5;
  const std::size_t leaked =
      extract_cloud(f, s.p.camera.intrinsics, s.g.count, half, 1, 0).size() - link;
  EXPECT_NEAR(static_cast<double>(leaked) / band, 0.5, 0.05);
  // Seeded: the same frame gives the same cloud; another frame index another draw.
  EXPECT_EQ(extract_cloud(f, s.p.camera.intrinsics, s.g.count, half, 1, 0).xyz,
            extract_cloud(f, s.p.camera.intrinsics, s.g.count, half, 1, 0).xyz);
  EXPECT_NE(extract_cloud(f, s.p.camera.intrinsics, s.g.count, half, 1, 0).xyz,
            extract_cloud(f, s.p.camera.intrinsics, s.g.count, half, 1, 1).xyz);
}

TEST(Extract, DepthModeRemovesTableAndWall) {
  TableScene s(NoiseParams::sr300());
  Sensor sensor(s.p, s.g, {}, s.background);
  const auto X = straight_chain(s.g);
  const DepthFrame f = sensor.render(X, 0.0, 3, 0);
  ExtractParams p;
  p.mode = ExtractParams::Mode::depth;
  const Cloud cloud = extract_cloud(f, s.p.camera.intrinsics, s.g.count, p, 3, 0);
  std::size_t on_link = 0;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Eigen::Vector3d q(cloud.xyz[3 * i], cloud.xyz[3 * i + 1], cloud.xyz[3 * i + 2]);
    on_link += distance_to_chain(q, s.p.camera.X_WC, X, s.g) < 0.005;
  }
  const std::size_t link = link_pixels(f, s.g.count);
  EXPECT_GT(static_cast<double>(on_link) / link, 0.95) << on_link << " of " << link;
  EXPECT_GT(static_cast<double>(on_link) / cloud.size(), 0.9)
      << cloud.size() - on_link << " background points left of " << cloud.size();
}

// remove_planes on a wall 0.5 m square (2.5 mm grid) and, 0.15 m in front of it, the
// front halves of 11 balls of r = 15 mm in a row at 45 mm (1 mm grid; 16% of the points):
// what the clutter scene's camera sees once the table has dropped out of view. The wall
// goes; the row of balls, which a plane holds within plane_threshold for much of its
// width, stays: without the width rule it is removed as the second plane.
TEST(Extract, DepthModeKeepsARowOfBallsThatLooksLikeAPlane) {
  Cloud cloud;
  std::size_t wall = 0;
  for (int i = 0; i <= 200; ++i)
    for (int j = 0; j <= 200; ++j, ++wall)
      cloud.push_back(static_cast<float>(-0.25 + 0.0025 * i), static_cast<float>(-0.25 + 0.0025 * j), 0.75F);
  constexpr double r = 0.015;
  for (int b = 0; b < 11; ++b)
    for (int i = -15; i <= 15; ++i)
      for (int j = -15; j <= 15; ++j) {
        const double x = 0.001 * i, y = 0.001 * j;
        if (x * x + y * y >= r * r) continue;
        cloud.push_back(static_cast<float>(-0.225 + 0.045 * b + x), static_cast<float>(y),
                        static_cast<float>(0.6 - std::sqrt(r * r - x * x - y * y)));
      }
  const std::size_t balls = cloud.size() - wall;
  ASSERT_GT(static_cast<double>(balls) / cloud.size(), 0.15);
  ExtractParams p;
  p.mode = ExtractParams::Mode::depth;
  const auto count = [&](const Cloud& c) {
    std::size_t on_wall = 0, on_balls = 0;
    for (std::size_t i = 0; i < c.size(); ++i) (c.xyz[3 * i + 2] > 0.7F ? on_wall : on_balls)++;
    return std::pair{on_wall, on_balls};
  };
  const auto [wall_left, balls_left] = count(remove_planes(cloud, p, 7));
  EXPECT_EQ(wall_left, 0u);
  EXPECT_EQ(balls_left, balls);
  p.min_plane_width = 0;
  const auto [wall_any, balls_any] = count(remove_planes(cloud, p, 7));
  EXPECT_EQ(wall_any, 0u);
  EXPECT_LT(static_cast<double>(balls_any) / balls, 0.7) << "the row of balls is not a plane to RANSAC";
}

TEST(Extract, BadParametersAreNamed) {
  ExtractParams p;
  p.leakage = 2;
  EXPECT_THROW(p.validate(), std::invalid_argument);
  try {
    p.validate();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("leakage"), std::string::npos);
  }
  ExtractParams narrow;
  narrow.min_plane_width = -0.1;
  const std::string e = test::error_of<std::invalid_argument>([&] { narrow.validate(); });
  EXPECT_NE(e.find("min_plane_width_m"), std::string::npos) << e;
  EXPECT_THROW((void)parse_extract_mode("colour"), std::invalid_argument);
}

}  // namespace
}  // namespace linksight::sim
