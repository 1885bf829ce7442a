#include <gtest/gtest.h>

#include <random>

#include "linksight/tracker/model.hpp"

namespace linksight {
namespace {

constexpr double kTol = 1e-12;

void expect_orthonormal(const Eigen::Matrix3d& R) {
  EXPECT_TRUE((R.transpose() * R).isApprox(Eigen::Matrix3d::Identity(), kTol)) << R;
  EXPECT_NEAR(R.determinant(), 1.0, kTol);
  EXPECT_TRUE(R.allFinite());
}

TEST(Model, EquationsThreeToEight) {
  const Eigen::Vector3d p_i(0.1, -0.2, 0.6), p_next(0.13, -0.17, 0.62);
  const ComponentFrame f = frame_from_points(p_i, p_next);
  EXPECT_FALSE(f.degenerate);
  const Eigen::Vector3d delta = p_next - p_i;
  const double d =
      std::sqrt(delta.x() * delta.x() + delta.y() * delta.y() + delta.z() * delta.z());  // Eq. 4
  const double h = std::sqrt(delta.y() * delta.y() + delta.z() * delta.z());             // Eq. 6
  const Eigen::Matrix3d R = f.X_CK.linear();
  // Eq. 3: Z points from p_i to p_{i+1}.
  EXPECT_TRUE(R.col(2).isApprox(delta / d, kTol));
  // Eq. 5 with X1 = 0: X2 = (p_{i+1,3} - p_i3)/h, X3 = (p_i2 - p_{i+1,2})/h.
  EXPECT_NEAR(R(0, 0), 0.0, kTol);
  EXPECT_NEAR(R(1, 0), delta.z() / h, kTol);
  EXPECT_NEAR(R(2, 0), -delta.y() / h, kTol);
  // Eq. 7: Y = Z × X = [-h/d, Δ1Δ2/(dh), Δ1Δ3/(dh)].
  EXPECT_NEAR(R(0, 1), -h / d, kTol);
  EXPECT_NEAR(R(1, 1), delta.x() * delta.y() / (d * h), kTol);
  EXPECT_NEAR(R(2, 1), delta.x() * delta.z() / (d * h), kTol);
  // Eq. 2: the origin is p_i.
  EXPECT_TRUE(f.X_CK.translation().isApprox(p_i, kTol));
  expect_orthonormal(R);
}

TEST(Model, RandomChainsGiveOrthonormalFrames) {
  std::mt19937_64 gen(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 200; ++trial) {
    Nodes nodes;
    Eigen::Vector3d p(u(gen), u(gen), 0.6 + u(gen));
    for (int k = 0; k < 12; ++k) {
      nodes.push_back(p);
      p += 0.045 * Eigen::Vector3d(u(gen), u(gen), u(gen)).normalized();
    }
    const auto frames = frames_from_nodes(nodes);
    ASSERT_EQ(frames.size(), 11u);  // M frames from M+1 points (Eq. 1)
    for (std::size_t i = 0; i < frames.size(); ++i) {
      expect_orthonormal(frames[i].X_CK.linear());
      EXPECT_TRUE(frames[i].X_CK.translation().isApprox(nodes[i], kTol));
      EXPECT_TRUE(
          frames[i].X_CK.linear().col(2).isApprox((nodes[i + 1] - nodes[i]).normalized(), 1e-9));
    }
  }
}

// The paper's X1 = 0 divides by h = 0 when Z is parallel to the camera x axis.
TEST(Model, ZAlongCameraXIsFiniteAndTakesNeighbourX) {
  const Nodes nodes = {{0, 0, 0.6}, {0.03, 0.0335, 0.6}, {0.075, 0.0335, 0.6}, {0.1, 0.07, 0.61}};
  const auto frames = frames_from_nodes(nodes);
  ASSERT_FALSE(frames[0].degenerate);
  ASSERT_TRUE(frames[1].degenerate);  // exactly along +x
  for (const auto& f : frames) expect_orthonormal(f.X_CK.linear());
  EXPECT_TRUE(frames[1].X_CK.linear().col(2).isApprox(Eigen::Vector3d::UnitX(), kTol));
  // X of the degenerate frame is the previous frame's X projected normal to Z.
  const Eigen::Vector3d X_prev = frames[0].X_CK.linear().col(0);
  const Eigen::Vector3d expected = (X_prev - X_prev.x() * Eigen::Vector3d::UnitX()).normalized();
  EXPECT_TRUE(frames[1].X_CK.linear().col(0).isApprox(expected, kTol));
}

TEST(Model, FramesAreContinuousThroughTheSingularDirection) {
  // Sweep Z through +x inside the degenerate cone: X must move by no more than Z does.
  const Eigen::Vector3d X_ref = Eigen::Vector3d(0.0, 0.6, -0.8);
  Eigen::Vector3d X_last = Eigen::Vector3d::Zero();
  for (int k = -10; k <= 10; ++k) {
    const double e = k * 0.05 * kFrameDegenerateSin;
    const Eigen::Vector3d Z = Eigen::Vector3d(1.0, e, 0.3 * e).normalized();
    const ComponentFrame f = frame_from_points(Eigen::Vector3d::Zero(), 0.045 * Z, X_ref);
    ASSERT_TRUE(f.degenerate);
    expect_orthonormal(f.X_CK.linear());
    const Eigen::Vector3d X = f.X_CK.linear().col(0);
    if (k > -10) {
      EXPECT_LT((X - X_last).norm(), 1e-6) << "step " << k;
    }
    X_last = X;
  }
  // Both sides of x give X near the reference, not the paper's sign flip.
  EXPECT_GT(X_last.dot(X_ref), 0.999);
}

TEST(Model, CoincidentPointsKeepReferenceAxis) {
  const ComponentFrame f =
      frame_from_points(Eigen::Vector3d(0.1, 0.2, 0.5), Eigen::Vector3d(0.1, 0.2, 0.5));
  EXPECT_TRUE(f.degenerate);
  expect_orthonormal(f.X_CK.linear());
  EXPECT_TRUE(f.X_CK.linear().col(2).isApprox(Eigen::Vector3d::UnitZ(), kTol));
}

TEST(Model, RejectsFewerThanTwoNodes) {
  try {
    (void)frames_from_nodes({Eigen::Vector3d::Zero()});
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("at least 2 nodes"), std::string::npos);
  }
}

}  // namespace
}  // namespace linksight
