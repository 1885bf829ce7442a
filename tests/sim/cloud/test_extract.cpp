// Cloud extraction from rendered frames (sim/extract): truth segmentation with leakage,
// depth segmentation with plane removal.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <tuple>
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

// Clouds for remove_planes [m, C]: a rectangle in the plane z = `z` on a 2.5 mm grid, and
// the front halves of 11 balls of r = 15 mm (1 mm grid) at 45 mm along an arc that turns
// by `bend` in all (0: a straight row), centred at x = 0, z = 0.6.
void add_rect(Cloud& c, double x0, double y0, double wx, double wy, double z) {
  for (int i = 0; i * 0.0025 <= wx + 1e-9; ++i)
    for (int j = 0; j * 0.0025 <= wy + 1e-9; ++j)
      c.push_back(static_cast<float>(x0 + 0.0025 * i), static_cast<float>(y0 + 0.0025 * j),
                  static_cast<float>(z));
}
void add_balls(Cloud& c, double bend = 0) {
  constexpr double r = 0.015, pitch = 0.045;
  for (int b = 0; b < 11; ++b) {
    // Along an arc in the image plane (x, y): the row seen from the front, bent sideways.
    const double k = bend / (10 * pitch), s = pitch * (b - 5);
    const double cx = bend == 0 ? s : std::sin(k * s) / k;
    const double cy = bend == 0 ? 0 : (1 - std::cos(k * s)) / k;
    for (int i = -15; i <= 15; ++i)
      for (int j = -15; j <= 15; ++j) {
        const double x = 0.001 * i, y = 0.001 * j;
        if (x * x + y * y >= r * r) continue;
        c.push_back(static_cast<float>(cx + x), static_cast<float>(cy + y),
                    static_cast<float>(0.6 - std::sqrt(r * r - x * x - y * y)));
      }
  }
}
// The balls' points in a cloud, told by depth: they lie in 0.585-0.6 m, the walls and
// strips of these tests farther away.
std::size_t balls_in(const Cloud& c) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < c.size(); ++i)
    n += c.xyz[3 * i + 2] > 0.58F && c.xyz[3 * i + 2] <= 0.6F;
  return n;
}

// remove_planes on what the clutter scene's camera sees once the table has dropped out of
// view: a wall 0.5 m square 0.15 m behind a row of 11 balls (16% of the points). The wall
// goes; the row, which a plane holds within plane_threshold for much of its width, stays:
// without the width rule it is removed as the second plane. Bent by up to 180 degrees, or
// with a small box face beside it that a plane through the row also catches, it stays too.
TEST(Extract, DepthModeKeepsARowOfBallsThatLooksLikeAPlane) {
  ExtractParams p;
  p.mode = ExtractParams::Mode::depth;
  for (const double bend : {0.0, std::numbers::pi / 2, std::numbers::pi}) {
    SCOPED_TRACE("bent by " + std::to_string(bend) + " rad");
    Cloud cloud;
    add_rect(cloud, -0.25, -0.25, 0.5, 0.5, 0.75);
    const std::size_t wall = cloud.size();
    add_balls(cloud, bend);
    const std::size_t balls = cloud.size() - wall;
    ASSERT_GT(static_cast<double>(balls) / cloud.size(), 0.15);
    const Cloud left = remove_planes(cloud, p, 7);
    EXPECT_EQ(left.size(), balls) << "the wall goes, every ball's point stays";
    EXPECT_EQ(balls_in(left), balls);
    ExtractParams any = p;
    any.min_plane_width = 0;
    EXPECT_LT(static_cast<double>(balls_in(remove_planes(cloud, any, 7))) / balls, 0.7)
        << "the row of balls is not a plane to RANSAC";
  }
  // A box face 8 cm square beside the row, level with the balls' front (z = 0.588): a plane
  // through the row catches it too, and the two together span far more than 0.1 m.
  Cloud cloud;
  add_rect(cloud, -0.25, -0.25, 0.5, 0.5, 0.75);
  const std::size_t wall = cloud.size();
  add_rect(cloud, 0.05, 0.06, 0.08, 0.08, 0.588);
  const std::size_t others = cloud.size();
  add_balls(cloud);
  const std::size_t balls = cloud.size() - others;
  const Cloud left = remove_planes(cloud, p, 7);
  std::size_t balls_left = 0;  // the box is at y >= 0.06, the row within 15 mm of y = 0
  for (std::size_t i = 0; i < left.size(); ++i)
    balls_left += left.xyz[3 * i + 1] < 0.03F && left.xyz[3 * i + 2] > 0.58F;
  EXPECT_EQ(balls_left, balls);
  EXPECT_EQ(left.size(), others - wall + balls) << "the box stays too; only the wall goes";
}

// A square of side `side` turned by `angle` about the optical axis, or a disc of diameter
// `side` (`disc`), centred on the axis at z = 0.7 m, sampled as a camera would: on a fixed
// 2.5 mm grid, whatever the angle [m, rad].
Cloud turned_shape(double side, double angle, bool disc) {
  Cloud c;
  const int n = static_cast<int>(side / 0.0025);
  for (int i = -n; i <= n; ++i)
    for (int j = -n; j <= n; ++j) {
      const double x = 0.0025 * i, y = 0.0025 * j;
      // In the shape's own frame.
      const double xs = std::cos(angle) * x + std::sin(angle) * y;
      const double ys = -std::sin(angle) * x + std::cos(angle) * y;
      const bool inside = disc ? xs * xs + ys * ys <= side * side / 4
                               : std::abs(xs) <= side / 2 && std::abs(ys) <= side / 2;
      if (inside) c.push_back(static_cast<float>(x), static_cast<float>(y), 0.7F);
    }
  return c;
}

// What counts as a plane, for min_plane_width = 0.1 m (7 x 7 cells of 20 mm): a strip
// 0.13 m wide (7 cells across) goes, strips 0.105 m (6 cells) and 0.09 m wide stay;
// squares 0.15 m wide and discs 0.175 m across go at any angle, though their principal
// axes fall anywhere (with one grid, along those axes, half the squares stay); narrower
// ones stay. A plane refused for its width does not stop the
// search (the row of balls is the best plane here and the wall, 0.15 m square with fewer
// points, is still found after it).
TEST(Extract, DepthModeRemovesPlanesThatCoverTheWidth) {
  ExtractParams p;
  p.mode = ExtractParams::Mode::depth;
  p.max_planes = 1;
  for (const auto& [width, removed] :
       {std::pair{0.13, true}, std::pair{0.105, false}, std::pair{0.09, false}}) {
    Cloud strip;
    add_rect(strip, -0.3, 0.0, 0.6, width, 0.7);
    EXPECT_EQ(remove_planes(strip, p, 7).size(), removed ? 0u : strip.size()) << width << " m";
  }
  for (int deg = 0; deg < 90; deg += 5) {
    const double a = deg * std::numbers::pi / 180;
    for (const auto& [side, disc, removed] :
         {std::tuple{0.15, false, true}, std::tuple{0.175, true, true},
          std::tuple{0.095, false, false}, std::tuple{0.13, true, false}}) {
      const Cloud shape = turned_shape(side, a, disc);
      EXPECT_EQ(remove_planes(shape, p, 7).size(), removed ? 0u : shape.size())
          << (disc ? "disc " : "square ") << side << " m at " << deg << " deg";
    }
  }
  Cloud cloud;
  add_balls(cloud);
  const std::size_t balls = cloud.size();
  add_rect(cloud, -0.075, -0.075, 0.15, 0.15, 0.75);  // fewer points than the row
  ASSERT_LT(cloud.size() - balls, balls);
  const Cloud left = remove_planes(cloud, p, 7);
  EXPECT_EQ(left.size(), balls) << "the wall is removed after the row is refused";
  EXPECT_EQ(balls_in(left), balls);
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
