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

ForceAction push(int component, const Eigen::Vector3d& force_W, double t0, double t1) {
  ForceAction a;
  a.component = component;
  a.force_W = force_W;
  a.t_start = t0;
  a.t_end = t1;
  return a;
}

// Largest drop of the mean ball height over the next `seconds`. A frictionless chain
// whips and swings, so one instant says little.
double max_mean_drop(World& w, double seconds) {
  auto mean_z = [](const Truth& t) {
    double z = 0;
    for (std::size_t k = 0; k < 11; ++k) z += t.nodes_W[k].z() / 11;
    return z;
  };
  const double z0 = mean_z(w.truth());
  double drop = 0;
  const int steps = static_cast<int>(std::lround(seconds / 0.001));
  for (int i = 0; i < steps; ++i) {
    w.step();
    drop = std::max(drop, z0 - mean_z(w.truth()));
  }
  return drop;
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

// Test 2 and the friction model: below the torque balance the chain sags, above it holds.
// Without friction it also swings (a whip), so the test watches the largest drop of the
// mean ball height, not one instant.
TEST(World, ChainSagsBelowTheHoldingPreloadAndHoldsAbove) {
  ChainParams c;
  const double needed =
      c.worst_gravity_torque() / (c.friction_coefficient * c.geometry.ball_radius);  // 270 N
  for (double factor : {0.0, 0.9, 1.1}) {
    c.preload_force = factor * needed;
    World w(c, WorldParams{}, base_at_half_metre());
    const double max_drop = max_mean_drop(w, 2.0);
    if (factor < 1.0) {
      EXPECT_GT(max_drop, 0.05) << "preload " << c.preload_force << " N should not hold";
    } else {
      EXPECT_LT(max_drop, 0.0005) << "preload " << c.preload_force << " N should hold";
    }
  }
}

// Test 3 (and 5): a sideways push at the tip above the holding torque bends the chain;
// released, it keeps the bent shape within 1 mm over 2 s.
TEST(World, PushBendsAndTheChainKeepsTheNewShape) {
  World w(ChainParams{}, WorldParams{}, base_at_half_metre());
  const Eigen::Vector3d tip0 = w.truth().nodes_W.back();
  w.add_force(push(10, Eigen::Vector3d(0, 20.0, 0), 0.2, 0.4));  // 20 N * 0.45 m = 9 N m >> 2 N m
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
    w.add_force(push(6, Eigen::Vector3d(3.0, 15.0, -4.0), 0.05, 0.15));
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
  w.add_force(push(10, Eigen::Vector3d(0, 1000.0, 0), 0.0, 0.05));
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
  w.add_force(push(8, Eigen::Vector3d(0, 10.0, 5.0), 0.0, 0.1));
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
  EXPECT_EQ(message(c), "chain.pitch_m = 0.025: must be >= 2 * ball_radius_m (balls would overlap)");
  c = {};
  c.preload_force = -1;
  EXPECT_EQ(message(c), "chain.preload_n = -1: must be in [0, 1000000]");
  c = {};
  c.cone_limit = 1.6;  // [rad]: the message is in the key's degrees
  EXPECT_NE(message(c).find("chain.cone_limit_deg = 91.67"), std::string::npos) << message(c);
  c = {};
  c.component_mass = 0;
  EXPECT_EQ(message(c), "chain.component_mass_kg = 0: must be in [1e-06, 100]");
  WorldParams p;
  p.dt = 0;
  EXPECT_EQ(message({}, p), "world.dt_s = 0: must be in [1e-05, 0.01]");
  World w(ChainParams{}, WorldParams{}, Eigen::Isometry3d::Identity());
  EXPECT_THROW(w.add_force(push(11, Eigen::Vector3d::Zero(), 0, 1)), std::invalid_argument);
}

// Test 4: pressed diagonally (both bend axes at once) and hard, no joint bends past the
// cone limit by more than 1 degree, and the limit is reached.
TEST(World, ConeLimitHoldsUnderAHardDiagonalPush) {
  ChainParams c;
  World w(c, WorldParams{}, base_at_half_metre());
  w.add_force(push(10, Eigen::Vector3d(0, 60.0, 60.0), 0.0, 1.0));
  double worst = 0.0;
  run(w, 1.5, [&](const Truth&) { worst = std::max(worst, w.max_bend()); });
  EXPECT_LE(worst, c.cone_limit + 1.0 * M_PI / 180.0);
  EXPECT_GT(worst, c.cone_limit - 2.0 * M_PI / 180.0) << "the push never reached the limit";
}

// Test 6: a base trajectory with no external load moves the chain rigidly.
TEST(World, BaseTrajectoryMovesTheChainRigidly) {
  const Eigen::Isometry3d X0 = base_at_half_metre();
  Eigen::Isometry3d X1 = X0;
  X1.translation() += Eigen::Vector3d(0.10, -0.05, 0.03);
  X1.linear() = Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  Sweep sweep;
  sweep.axis_B = Eigen::Vector3d::UnitY();
  sweep.amplitude = 0.1;
  sweep.frequency = 0.5;
  const BaseTrajectory trajectory({{0.0, X0}, {1.0, X1}}, {sweep});
  World w(ChainParams{}, WorldParams{}, X0);
  w.set_base_trajectory(trajectory);
  const Truth start = w.truth();
  std::vector<Eigen::Vector3d> in_base;
  for (const auto& p : start.nodes_W) in_base.push_back(trajectory.pose(0.0).inverse() * p);
  double worst = 0.0;
  run(w, 2.0, [&](const Truth& t) {
    const Eigen::Isometry3d X_BW = trajectory.pose(t.t).inverse();
    for (std::size_t j = 0; j < t.nodes_W.size(); ++j) {
      worst = std::max(worst, (X_BW * t.nodes_W[j] - in_base[j]).norm());
    }
  });
  EXPECT_LT(worst, 0.0005);
  // It really moved.
  EXPECT_GT((w.truth().nodes_W.back() - start.nodes_W.back()).norm(), 0.05);
}

// A kinematic sphere swept through the chain's tip: it touches, bends, and leaves a bend.
TEST(World, PusherBendsTheChainOnContact) {
  World w(ChainParams{}, WorldParams{}, base_at_half_metre());
  const Eigen::Vector3d tip0 = w.truth().nodes_W[10];
  PusherParams pusher;
  pusher.radius = 0.02;
  Eigen::Isometry3d A = Eigen::Isometry3d::Identity(), B = Eigen::Isometry3d::Identity();
  A.translation() = tip0 + Eigen::Vector3d(0, -0.08, 0);
  B.translation() = tip0 + Eigen::Vector3d(0, 0.04, 0);
  pusher.path = BaseTrajectory({{0.1, A}, {0.6, B}, {0.8, A}});
  w.add_pusher(pusher);
  bool touched = false;
  run(w, 1.5, [&](const Truth& t) { touched |= t.contact; });
  EXPECT_TRUE(touched);
  EXPECT_FALSE(w.truth().contact);  // the pusher went back
  EXPECT_GT(w.truth().nodes_W[10].y() - tip0.y(), 0.02) << "the chain did not bend";
  EXPECT_LE(w.max_bend(), ChainParams{}.cone_limit + 1.0 * M_PI / 180.0);
}

// With half the preload it needs, the chain slips down onto a box below it and rests there.
TEST(World, ObstacleStopsTheChain) {
  ChainParams c;
  c.preload_force =
      0.5 * c.worst_gravity_torque() / (c.friction_coefficient * c.geometry.ball_radius);
  World w(c, WorldParams{}, base_at_half_metre());
  ObstacleParams box;
  box.half_extents = Eigen::Vector3d(0.2, 0.2, 0.05);
  box.X_WO.translation() = Eigen::Vector3d(0.35, 0.0, 0.40);  // top at z = 0.45
  w.add_obstacle(box);
  run(w, 2.0);
  const Truth t = w.truth();
  EXPECT_TRUE(t.contact);
  for (std::size_t k = 6; k < 11; ++k) {
    EXPECT_GT(t.nodes_W[k].z(), 0.45 + 0.015 - 0.003) << "ball " << k << " sank into the box";
  }
}

TEST(World, TorqueActionTurnsTheChain) {
  World w(ChainParams{}, WorldParams{}, base_at_half_metre());
  w.add_force({0, Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, 6.0), 0.0, 0.2});  // > 2 N m
  const Eigen::Vector3d tip0 = w.truth().nodes_W.back();
  run(w, 0.8);
  EXPECT_GT(w.truth().nodes_W.back().y() - tip0.y(), 0.02);
}

TEST(BaseTrajectory, InterpolatesAndHolds) {
  Eigen::Isometry3d A = Eigen::Isometry3d::Identity(), B = Eigen::Isometry3d::Identity();
  B.translation() = Eigen::Vector3d(1, 2, 3);
  B.linear() = Eigen::AngleAxisd(1.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const BaseTrajectory tr({{1.0, A}, {3.0, B}});
  EXPECT_TRUE(tr.pose(0.0).isApprox(A));
  EXPECT_TRUE(tr.pose(5.0).isApprox(B));
  const Eigen::Isometry3d mid = tr.pose(2.0);
  EXPECT_TRUE(mid.translation().isApprox(Eigen::Vector3d(0.5, 1, 1.5)));
  EXPECT_NEAR(Eigen::AngleAxisd(mid.rotation()).angle(), 0.5, 1e-12);  // slerp halfway
  Sweep s;
  s.offset_W = Eigen::Vector3d(0, 0, 0.1);
  s.frequency = 1.0;
  const BaseTrajectory sw({}, {s});
  EXPECT_NEAR(sw.pose(0.25).translation().z(), 0.1, 1e-12);
  EXPECT_THROW(BaseTrajectory({{1.0, A}, {1.0, B}}), std::invalid_argument);
}

// Gravity scripted in time: a chain with no preload floats while gravity is off and
// falls once it is switched on.
TEST(World, GravitySwitchedInTime) {
  ChainParams c;
  c.preload_force = 0.0;
  World w(c, WorldParams{}, base_at_half_metre());
  w.add_gravity_switch({0.0, false});
  w.add_gravity_switch({1.0, true});
  const Eigen::Vector3d tip0 = w.truth().nodes_W.back();
  run(w, 1.0);
  EXPECT_LT((w.truth().nodes_W.back() - tip0).norm(), 1e-4);
  // Once on, the chain falls.
  const double max_drop = max_mean_drop(w, 1.0);
  EXPECT_GT(max_drop, 0.05);
}

}  // namespace
}  // namespace linksight::sim
