// chain_state.hpp: the chain as a state whose pitch holds whatever values it takes.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "linksight/tracker/chain_state.hpp"

namespace linksight {
namespace {

constexpr double kStatePitchTolerance = 1e-12;  // [m]: issue 17 asks for 1e-6; the state gives rounding only
constexpr double kDeg = std::numbers::pi / 180;

// A random chain: every axis any unit vector (bends of any size).
ChainState random_chain(std::mt19937_64& rng, int count) {
  std::normal_distribution<double> g;
  ChainState s;
  s.c0 = Eigen::Vector3d(g(rng), g(rng), g(rng) + 1.0);
  for (int k = 0; k < count; ++k) s.axis.push_back(Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized());
  return s;
}

TEST(ChainState, EveryPitchHoldsWhateverTheState) {
  const ComponentGeometry geo;
  std::mt19937_64 rng(7);
  for (int trial = 0; trial < 100; ++trial) {
    const ChainState s = random_chain(rng, geo.count);
    const Nodes n = s.nodes(geo.pitch);
    ASSERT_EQ(n.size(), static_cast<std::size_t>(geo.count + 1));
    for (std::size_t k = 0; k + 1 < n.size(); ++k)
      EXPECT_NEAR((n[k + 1] - n[k]).norm(), geo.pitch, kStatePitchTolerance) << "trial " << trial;
    for (int k = 0; k <= geo.count; ++k)
      EXPECT_EQ(s.centre(k, geo.pitch), n[static_cast<std::size_t>(k)]);  // one sum, one order
  }
}

TEST(ChainState, FromNodesKeepsDirectionsAndRestoresThePitch) {
  const ComponentGeometry geo;
  std::mt19937_64 rng(3);
  const ChainState s = random_chain(rng, geo.count);
  Nodes n = s.nodes(geo.pitch);
  const ChainState back = chain_from_nodes(n, geo);
  for (std::size_t k = 0; k < s.axis.size(); ++k)
    EXPECT_LT((back.axis[k] - s.axis[k]).norm(), 1e-12) << k;
  // Stretched nodes (a surface tracker's output): directions kept, the pitch exact again.
  for (std::size_t k = 0; k < n.size(); ++k) n[k] = n[0] + 1.3 * (n[k] - n[0]);
  const Nodes fixed = chain_from_nodes(n, geo).nodes(geo.pitch);
  for (std::size_t k = 0; k + 1 < fixed.size(); ++k)
    EXPECT_NEAR((fixed[k + 1] - fixed[k]).norm(), geo.pitch, kStatePitchTolerance);
  // Coincident nodes carry the previous direction.
  n = s.nodes(geo.pitch);
  n[5] = n[4];
  EXPECT_EQ(chain_from_nodes(n, geo).axis[4], chain_from_nodes(n, geo).axis[3]);
  EXPECT_THROW((void)chain_from_nodes(Nodes(3), geo), std::invalid_argument);
  n[2].x() = std::nan("");
  EXPECT_THROW((void)chain_from_nodes(n, geo), std::invalid_argument);
}

TEST(ChainState, BendsBeyondTheConeAreBentBackExactlyToIt) {
  const ComponentGeometry geo;
  const double limit = 25 * kDeg;
  std::mt19937_64 rng(11);
  for (int trial = 0; trial < 50; ++trial) {
    ChainState s = random_chain(rng, geo.count);
    const int bent = limit_bends(s, limit);
    EXPECT_GT(bent, 0);  // random axes bend far more than 25 degrees somewhere
    EXPECT_LE(s.max_bend(), limit + 1e-9) << "trial " << trial;
    for (const Eigen::Vector3d& a : s.axis) EXPECT_NEAR(a.norm(), 1.0, 1e-12);
    const Nodes n = s.nodes(geo.pitch);
    for (std::size_t k = 0; k + 1 < n.size(); ++k)
      EXPECT_NEAR((n[k + 1] - n[k]).norm(), geo.pitch, kStatePitchTolerance);
  }
  // A chain within the cone is left bit for bit.
  ChainState straight;
  for (int k = 0; k < geo.count; ++k)
    straight.axis.push_back(Eigen::Vector3d(std::cos(k * 2 * kDeg), std::sin(k * 2 * kDeg), 0));
  const ChainState before = straight;
  EXPECT_EQ(limit_bends(straight, limit), 0);
  for (std::size_t k = 0; k < straight.axis.size(); ++k) EXPECT_EQ(straight.axis[k], before.axis[k]);
  // A joint folded back on itself still ends at the limit.
  ChainState folded = before;
  folded.axis[4] = -folded.axis[3];
  // Joint 4 turns toward the next axis's side: 31 degrees, which axis 5 (10 degrees) is
  // within 25 degrees of.
  EXPECT_EQ(limit_bends(folded, limit), 1);
  EXPECT_NEAR(std::acos(folded.axis[4].dot(before.axis[3])), limit, 1e-12);
  EXPECT_LE(folded.max_bend(), limit + 1e-9);
  EXPECT_THROW((void)limit_bends(folded, -0.1), std::invalid_argument);
}

}  // namespace
}  // namespace linksight
