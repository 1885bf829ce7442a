#include <gtest/gtest.h>

#include <random>

#include "linksight/tracker/model.hpp"

namespace linksight {
namespace {

constexpr double kRotationTol = 1e-12;

void expect_orthonormal(const Eigen::Matrix3d& R) {
  EXPECT_TRUE((R.transpose() * R).isApprox(Eigen::Matrix3d::Identity(), kRotationTol)) << R;
  EXPECT_NEAR(R.determinant(), 1.0, kRotationTol);
  EXPECT_TRUE(R.allFinite());
}

TEST(Model, EquationsThreeToEight) {
  const Eigen::Vector3d p_i(0.1, -0.2, 0.6), p_next(0.13, -0.17, 0.62);
  const ComponentFrame f = frame_from_points(p_i, p_next);
  EXPECT_FALSE(f.carried);
  const Eigen::Vector3d delta = p_next - p_i;
  const double d =
      std::sqrt(delta.x() * delta.x() + delta.y() * delta.y() + delta.z() * delta.z());  // Eq. 4
  const double h = std::sqrt(delta.y() * delta.y() + delta.z() * delta.z());             // Eq. 6
  const Eigen::Matrix3d R = f.X_CK.linear();
  // Eq. 3: Z points from p_i to p_{i+1}.
  EXPECT_TRUE(R.col(2).isApprox(delta / d, kRotationTol));
  // Eq. 5 with X1 = 0: X2 = (p_{i+1,3} - p_i3)/h, X3 = (p_i2 - p_{i+1,2})/h.
  EXPECT_NEAR(R(0, 0), 0.0, kRotationTol);
  EXPECT_NEAR(R(1, 0), delta.z() / h, kRotationTol);
  EXPECT_NEAR(R(2, 0), -delta.y() / h, kRotationTol);
  // Eq. 7: Y = Z × X = [-h/d, Δ1Δ2/(dh), Δ1Δ3/(dh)].
  EXPECT_NEAR(R(0, 1), -h / d, kRotationTol);
  EXPECT_NEAR(R(1, 1), delta.x() * delta.y() / (d * h), kRotationTol);
  EXPECT_NEAR(R(2, 1), delta.x() * delta.z() / (d * h), kRotationTol);
  // Eq. 2: the origin is p_i.
  EXPECT_TRUE(f.X_CK.translation().isApprox(p_i, kRotationTol));
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
      EXPECT_TRUE(frames[i].X_CK.translation().isApprox(nodes[i], kRotationTol));
      EXPECT_TRUE(
          frames[i].X_CK.linear().col(2).isApprox((nodes[i + 1] - nodes[i]).normalized(), 1e-9));
    }
  }
}

double angle(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

// Rotation-minimizing along the chain: X turns between neighbours by no more than Z does,
// also where a segment lies exactly on the camera x axis (h = 0 in Eq. 6).
TEST(Model, ChainFramesTurnOnlyWithTheBendEvenAlongCameraX) {
  const Nodes nodes = {{-0.02, 0.01, 0.6}, {0.0, 0.0, 0.6},    {0.045, 0.0, 0.6},
                       {0.09, 0.0, 0.6},   {0.13, 0.02, 0.61}, {0.17, 0.03, 0.6}};
  const auto frames = frames_from_nodes(nodes);
  ASSERT_TRUE(frames[1].X_CK.linear().col(2).isApprox(Eigen::Vector3d::UnitX(), kRotationTol));
  for (std::size_t i = 0; i < frames.size(); ++i) {
    expect_orthonormal(frames[i].X_CK.linear());
    if (i == 0) continue;
    const Eigen::Matrix3d R0 = frames[i - 1].X_CK.linear(), R1 = frames[i].X_CK.linear();
    EXPECT_LE(angle(R0.col(0), R1.col(0)), angle(R0.col(2), R1.col(2)) + 1e-9) << i;
  }
  std::mt19937_64 gen(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Nodes chain = {Eigen::Vector3d(0, 0, 0.6)};
  Eigen::Vector3d dir = Eigen::Vector3d::UnitX();
  for (int k = 0; k < 11; ++k) {  // bends up to ~25 degrees, as the joint cone allows
    dir = (dir + 0.45 * Eigen::Vector3d(u(gen), u(gen), u(gen))).normalized();
    chain.push_back(chain.back() + 0.045 * dir);
  }
  const auto rmf = frames_from_nodes(chain);
  for (std::size_t i = 1; i < rmf.size(); ++i) {
    EXPECT_LE(angle(rmf[i - 1].X_CK.linear().col(0), rmf[i].X_CK.linear().col(0)),
              angle(rmf[i - 1].X_CK.linear().col(2), rmf[i].X_CK.linear().col(2)) + 1e-9);
  }
}

// The paper's X1 = 0 divides by h = 0 when Z is parallel to the camera x axis, and near
// it X flips by 180 degrees as Z crosses the axis. Sweep Z through +x on great circles in
// several planes: the rule's X moves by little per step where Eq. 5 jumps.
TEST(Model, FrameIsContinuousAsZPassesThroughCameraX) {
  const double step = 0.05 * M_PI / 180.0;
  for (double phi_deg : {0.0, 30.0, 60.0, 150.0, 200.0}) {
    const double phi = phi_deg * M_PI / 180.0;
    Eigen::Vector3d X_last = Eigen::Vector3d::Zero();
    double max_step = 0.0, paper_jump = 0.0;
    for (double t = -40.0 * M_PI / 180.0; t <= 40.0 * M_PI / 180.0; t += step) {
      const Eigen::Vector3d Z(std::cos(t), std::sin(t) * std::cos(phi),
                              std::sin(t) * std::sin(phi));
      const ComponentFrame f =
          frame_from_points(Eigen::Vector3d(0, 0, 0.5), Eigen::Vector3d(0, 0, 0.5) + 0.045 * Z);
      expect_orthonormal(f.X_CK.linear());
      const Eigen::Vector3d X = f.X_CK.linear().col(0);
      if (X_last != Eigen::Vector3d::Zero()) max_step = std::max(max_step, (X - X_last).norm());
      X_last = X;
      const Eigen::Vector3d Zn(std::cos(t + step), std::sin(t + step) * std::cos(phi),
                               std::sin(t + step) * std::sin(phi));
      const Eigen::Vector3d P0 = Eigen::Vector3d(0, Z.z(), -Z.y()).normalized();
      const Eigen::Vector3d P1 = Eigen::Vector3d(0, Zn.z(), -Zn.y()).normalized();
      paper_jump = std::max(paper_jump, (P1 - P0).norm());
    }
    EXPECT_LT(max_step, 0.05) << "plane " << phi_deg;
    EXPECT_GT(paper_jump, 1.9) << "plane " << phi_deg;  // Eq. 5 alone flips X
  }
}

TEST(Model, ExactlyAlongCameraXIsFinite) {
  for (double sign : {1.0, -1.0}) {
    const ComponentFrame f = frame_from_points(Eigen::Vector3d(0.1, 0, 0.5),
                                               Eigen::Vector3d(0.1 + sign * 0.045, 0, 0.5));
    EXPECT_TRUE(f.carried);
    expect_orthonormal(f.X_CK.linear());
    EXPECT_TRUE(f.X_CK.linear().col(0).isApprox(Eigen::Vector3d::UnitY(), kRotationTol));  // the reference
  }
}

TEST(Model, CoincidentPointsKeepReferenceAxis) {
  const ComponentFrame f =
      frame_from_points(Eigen::Vector3d(0.1, 0.2, 0.5), Eigen::Vector3d(0.1, 0.2, 0.5));
  EXPECT_TRUE(f.carried);
  expect_orthonormal(f.X_CK.linear());
  EXPECT_TRUE(f.X_CK.linear().col(2).isApprox(Eigen::Vector3d::UnitZ(), kRotationTol));
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
