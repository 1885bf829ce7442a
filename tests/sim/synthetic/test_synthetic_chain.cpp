#include <gtest/gtest.h>

#include "linksight/sim/synthetic_chain.hpp"
#include "test_support.hpp"

namespace linksight::sim {
namespace {

TEST(ChainNodes, BallsAtPitchAndBendsAsAsked) {
  const ComponentGeometry g;
  const Nodes n =
      chain_nodes(g, shape_bends(ChainShape::c_shape, g.count, 0.1), Eigen::Isometry3d::Identity());
  ASSERT_EQ(n.size(), 12u);
  for (std::size_t j = 0; j + 1 < n.size(); ++j)
    EXPECT_NEAR((n[j + 1] - n[j]).norm(), g.pitch, 1e-12);
  for (std::size_t j = 1; j + 1 < n.size(); ++j) {
    const double angle =
        std::acos((n[j] - n[j - 1]).normalized().dot((n[j + 1] - n[j]).normalized()));
    EXPECT_NEAR(angle, 0.1, 1e-9);
  }
  EXPECT_THROW((void)chain_nodes(g, {0.1}, Eigen::Isometry3d::Identity()), std::invalid_argument);
}

TEST(SurfaceSampling, PointsLieOnCameraFacingSurfaces) {
  const ComponentGeometry g;
  const Nodes n = test::test_chain(ChainShape::s_shape);
  SurfaceSampling s;
  const Cloud c = sample_visible_surface(n, g, s);
  ASSERT_GT(c.size(), 5000u);
  for (std::size_t i = 0; i < c.size(); ++i) {
    const Eigen::Vector3d p = c.point(i);
    double ball = 1e9;
    std::size_t k = 0;
    for (std::size_t j = 0; j < 11; ++j) {
      if ((p - n[j]).norm() < ball) {
        ball = (p - n[j]).norm();
        k = j;
      }
    }
    const bool on_ball = std::abs(ball - g.ball_radius) < 1e-6;
    if (on_ball) {
      EXPECT_LT((p - n[k]).dot(p), 1e-9) << "ball point facing away";
    }
    double neck = 1e9;
    for (std::size_t j = 0; j < 11; ++j) {
      const Eigen::Vector3d axis = (n[j + 1] - n[j]).normalized();
      const double t = std::clamp((p - n[j]).dot(axis), 0.0, g.neck_length);
      neck = std::min(neck, (p - n[j] - t * axis).norm());
    }
    EXPECT_TRUE(on_ball || std::abs(neck - g.neck_radius) < 1e-6) << "point " << i;
  }
}

TEST(SurfaceSampling, SeededHiddenAndNoisy) {
  const Nodes n = test::test_chain(ChainShape::straight);
  SurfaceSampling s;
  s.noise_sigma = 0.001;
  const Cloud a = sample_visible_surface(n, {}, s);
  const Cloud b = sample_visible_surface(n, {}, s);
  EXPECT_EQ(a.xyz, b.xyz);
  s.seed = 2;
  EXPECT_NE(sample_visible_surface(n, {}, s).xyz, a.xyz);
  // Ball 3 hidden: no point lies on its surface (1 mm noise: within 4 sigma of r). Necks
  // off, because the neighbouring neck's cap lies 16.6 mm from ball 3's centre.
  s.necks = false;
  auto near_ball3 = [&](const Cloud& c) {
    int count = 0;
    for (std::size_t i = 0; i < c.size(); ++i)
      count += std::abs((c.point(i) - n[3]).norm() - 0.015) < 0.004;
    return count;
  };
  EXPECT_GT(near_ball3(sample_visible_surface(n, {}, s)), 300);
  s.hidden = {3};
  EXPECT_EQ(near_ball3(sample_visible_surface(n, {}, s)), 0);
  s.hidden = {11};
  EXPECT_THROW((void)sample_visible_surface(n, {}, s), std::invalid_argument);
}

TEST(DemoNodes, MovesAndStaysInFrontOfTheCamera) {
  const ComponentGeometry g;
  const Nodes a = demo_nodes(g, 0, 30), b = demo_nodes(g, 30, 30);
  EXPECT_GT((a[11] - b[11]).norm(), 0.01);
  for (const auto& p : b) EXPECT_GT(p.z(), 0.4);
}

}  // namespace
}  // namespace linksight::sim
