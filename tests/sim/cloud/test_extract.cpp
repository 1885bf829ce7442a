// Cloud extraction from rendered frames (sim/extract): truth segmentation with leakage,
// depth segmentation with plane removal.
#include <gtest/gtest.h>

#include <numbers>

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

TEST(Extract, BadParametersAreNamed) {
  ExtractParams p;
  p.leakage = 2;
  EXPECT_THROW(p.validate(), std::invalid_argument);
  try {
    p.validate();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("leakage"), std::string::npos);
  }
  EXPECT_THROW((void)parse_extract_mode("colour"), std::invalid_argument);
}

}  // namespace
}  // namespace linksight::sim
