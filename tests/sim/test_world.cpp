// The Bullet chain: it holds its shape by preload friction, bends under a load above the
// holding torque and keeps the new shape. All truth in the world frame W (z up).
#include <gtest/gtest.h>

#include <functional>

#include "linksight/sim/world.hpp"

namespace linksight::sim {
namespace {

constexpr double kPitchTolerance = 1e-4;  // neighbour distance stays d within 0.1 mm

Eigen::Isometry3d base_at_half_metre() {
  Eigen::Isometry3d X_WB = Eigen::Isometry3d::Identity();
  X_WB.translation() = Eigen::Vector3d(0, 0, 0.5);
  return X_WB;
}

double max_pitch_error(const Truth& t, double pitch) {
  double e = 0;
  for (std::size_t j = 0; j + 1 < t.nodes_W.size(); ++j) {
    e = std::max(e, std::abs((t.nodes_W[j + 1] - t.nodes_W[j]).norm() - pitch));
  }
  return e;
}

void run(World& w, double seconds, const std::function<void(const Truth&)>& each = {}) {
  const int steps = static_cast<int>(std::lround(seconds / 0.001));
  for (int i = 0; i < steps; ++i) {
    w.step();
    if (each) each(w.truth());
  }
}

TEST(ChainParams, DefaultHoldsItsOwnWeightWithMargin) {
  const ChainParams c;
  EXPECT_NO_THROW(c.validate());
  EXPECT_GE(c.holding_torque() / c.worst_gravity_torque(), 1.5);
}

// Test 1: default preload, base held horizontal for 5 s.
TEST(World, DefaultPreloadHoldsTheHorizontalChain) {
  World w(ChainParams{}, WorldParams{}, base_at_half_metre());
  const Eigen::Vector3d tip0 = w.truth().nodes_W.back();
  EXPECT_TRUE(tip0.isApprox(Eigen::Vector3d(11 * 0.045, 0, 0.5), 1e-6)) << tip0.transpose();
  double worst_pitch = 0;
  run(w, 5.0,
      [&](const Truth& t) { worst_pitch = std::max(worst_pitch, max_pitch_error(t, 0.045)); });
  const Truth t = w.truth();
  EXPECT_NEAR(t.t, 5.0, 1e-9);
  EXPECT_LT((t.nodes_W.back() - tip0).norm(), 0.0005);  // tip drift < 0.5 mm
  EXPECT_LT(worst_pitch, kPitchTolerance);
  EXPECT_FALSE(t.contact);
}

// Test 2 and the friction model: the threshold is where the torque balance puts it.
TEST(World, ChainSagsBelowTheHoldingPreloadAndHoldsAbove) {
  ChainParams c;
  const double needed =
      c.worst_gravity_torque() / (c.friction_coefficient * c.geometry.ball_radius);  // 270 N
  for (double factor : {0.0, 0.9, 1.1}) {
    c.preload_force = factor * needed;
    World w(c, WorldParams{}, base_at_half_metre());
    const Eigen::Vector3d tip0 = w.truth().nodes_W.back();
    run(w, 2.0);
    const double drop = tip0.z() - w.truth().nodes_W.back().z();
    if (factor < 1.0) {
      EXPECT_GT(drop, 0.05) << "preload " << c.preload_force << " N should not hold";
    } else {
      EXPECT_LT(drop, 0.0005) << "preload " << c.preload_force << " N should hold";
    }
  }
}

// Test 3 (and 5): a sideways push at the tip above the holding torque bends the chain;
// released, it keeps the bent shape within 1 mm over 2 s.
TEST(World, PushBendsAndTheChainKeepsTheNewShape) {
  World w(ChainParams{}, WorldParams{}, base_at_half_metre());
  const Eigen::Vector3d tip0 = w.truth().nodes_W.back();
  w.add_force({10, Eigen::Vector3d(0, 20.0, 0), 0.2, 0.4});  // 20 N * 0.45 m = 9 N m >> 2 N m
  double worst_pitch = 0;
  auto pitch = [&](const Truth& t) {
    worst_pitch = std::max(worst_pitch, max_pitch_error(t, 0.045));
  };
  run(w, 1.0, pitch);  // push, then 0.6 s to come to rest
  const Truth bent = w.truth();
  EXPECT_GT((bent.nodes_W.back() - tip0).norm(), 0.02) << "the push did not bend the chain";
  run(w, 2.0, pitch);
  const Truth later = w.truth();
  for (std::size_t j = 0; j < later.nodes_W.size(); ++j) {
    EXPECT_LT((later.nodes_W[j] - bent.nodes_W[j]).norm(), 0.001) << "node " << j;
  }
  EXPECT_LT(worst_pitch, kPitchTolerance);
}

// Test 7: same inputs, bitwise-identical truth.
TEST(World, SameInputsGiveBitwiseIdenticalTruth) {
  auto simulate = [] {
    World w(ChainParams{}, WorldParams{}, base_at_half_metre());
    w.add_force({6, Eigen::Vector3d(3.0, 15.0, -4.0), 0.05, 0.15});
    run(w, 0.4);
    return w.truth();
  };
  const Truth a = simulate(), b = simulate();
  EXPECT_EQ(a.nodes_W, b.nodes_W);
  EXPECT_EQ(a.joint_angles, b.joint_angles);
}

// Test 8: a violent push gives no NaN and no explosion.
TEST(World, ViolentPushStaysFiniteAndConnected) {
  World w(ChainParams{}, WorldParams{}, base_at_half_metre());
  w.add_force({10, Eigen::Vector3d(0, 1000.0, 0), 0.0, 0.05});
  double worst_pitch = 0;
  run(w, 1.0, [&](const Truth& t) {
    for (const auto& p : t.nodes_W) {
      ASSERT_TRUE(p.allFinite());
      ASSERT_LT((p - Eigen::Vector3d(0, 0, 0.5)).norm(), 0.55);  // never beyond its own length
    }
    worst_pitch = std::max(worst_pitch, max_pitch_error(t, 0.045));
  });
  EXPECT_LT(worst_pitch, kPitchTolerance);
}

// Truth layout: 11 centres + tip, component frames with Z toward the next ball.
TEST(World, TruthFramesFollowThePaperModel) {
  World w(ChainParams{}, WorldParams{}, base_at_half_metre());
  w.add_force({8, Eigen::Vector3d(0, 10.0, 5.0), 0.0, 0.1});
  run(w, 0.5);
  const Truth t = w.truth();
  ASSERT_EQ(t.nodes_W.size(), 12u);
  ASSERT_EQ(t.X_WK.size(), 11u);
  EXPECT_EQ(t.joint_angles.size(), 33u);
  for (std::size_t k = 0; k < 11; ++k) {
    EXPECT_TRUE(t.X_WK[k].translation().isApprox(t.nodes_W[k], 1e-12));
    const Eigen::Vector3d Z = t.X_WK[k].linear().col(2);
    EXPECT_LT((Z - (t.nodes_W[k + 1] - t.nodes_W[k]).normalized()).norm(), 1e-4) << k;
    EXPECT_NEAR(t.X_WK[k].linear().determinant(), 1.0, 1e-5);
  }
}

// Test 9: out-of-range parameters name the parameter.
TEST(World, BadParametersNameTheParameter) {
  auto message = [](const ChainParams& c, const WorldParams& p = {}) {
    try {
      World w(c, p, Eigen::Isometry3d::Identity());
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  ChainParams c;
  c.geometry.ball_radius = 0;
  EXPECT_NE(message(c).find("ball_radius"), std::string::npos);
  c = {};
  c.geometry.pitch = 0.025;  // < 2 r
  c.geometry.neck_length = 0.02;
  EXPECT_NE(message(c).find("ChainParams.geometry.pitch = 0.025"), std::string::npos) << message(c);
  c = {};
  c.preload_force = -1;
  EXPECT_NE(message(c).find("ChainParams.preload_force = -1"), std::string::npos);
  c = {};
  c.cone_limit = 1.6;
  EXPECT_NE(message(c).find("ChainParams.cone_limit"), std::string::npos);
  c = {};
  c.component_mass = 0;
  EXPECT_NE(message(c).find("ChainParams.component_mass"), std::string::npos);
  WorldParams p;
  p.dt = 0;
  EXPECT_NE(message({}, p).find("WorldParams.dt = 0"), std::string::npos);
  World w(ChainParams{}, WorldParams{}, Eigen::Isometry3d::Identity());
  EXPECT_THROW(w.add_force({11, Eigen::Vector3d::Zero(), 0, 1}), std::invalid_argument);
}

}  // namespace
}  // namespace linksight::sim
