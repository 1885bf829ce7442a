// chain_fit.hpp: the chain fitted to the surface points, centres without the surface bias.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <tuple>

#include "linksight/sim/synthetic_chain.hpp"
#include "linksight/tracker/chain_fit.hpp"
#include "test_support.hpp"

namespace linksight {
namespace {

constexpr double kNoiseFreeBand = 0.05e-3;  // [m]: issue 17's noise-free target
constexpr double kNoisyMeanBand = 0.5e-3;   // [m]: issue 17's sr300 target (mean)
constexpr double kPitchTolerance = 1e-9;    // [m]: issue 17 asks for 1e-6

// The standard test link at `distance` from the camera (its bending plane tilted toward it).
Nodes chain_at(sim::ChainShape shape, double distance, const ComponentGeometry& g) {
  Eigen::Isometry3d X_CB = Eigen::Isometry3d::Identity();
  X_CB.translation() = Eigen::Vector3d(-0.22, -0.02, distance);
  X_CB.linear() = Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitX()).toRotationMatrix();
  return sim::chain_nodes(g, sim::shape_bends(shape, g.count, 0.15), X_CB);
}

// The truth moved: ball 0 by a few millimetres and every axis turned by about 2 degrees.
ChainState perturbed(const Nodes& truth, const ComponentGeometry& g, std::uint64_t seed) {
  ChainState s = chain_from_nodes(truth, g);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n(0.0, 1.0);
  s.c0 += Eigen::Vector3d(0.002, -0.001, 0.003);
  for (Eigen::Vector3d& a : s.axis) {
    const Eigen::Vector3d w = Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized();
    a = (Eigen::AngleAxisd(2.0 * M_PI / 180, w) * a).normalized();
  }
  return s;
}

double max_error(const Nodes& a, const Nodes& b) {
  double m = 0;
  for (std::size_t k = 0; k < a.size(); ++k) m = std::max(m, (a[k] - b[k]).norm());
  return m;
}
double mean_error(const Nodes& a, const Nodes& b) {
  double m = 0;
  for (std::size_t k = 0; k < a.size(); ++k) m += (a[k] - b[k]).norm();
  return m / static_cast<double>(a.size());
}
void expect_pitch(const ChainState& s, const ComponentGeometry& g) {
  const Nodes n = s.nodes(g.pitch);
  for (std::size_t k = 0; k + 1 < n.size(); ++k)
    EXPECT_NEAR((n[k + 1] - n[k]).norm(), g.pitch, kPitchTolerance) << "between " << k;
}

using Case = std::tuple<sim::ChainShape, double>;
class ChainFit : public ::testing::TestWithParam<Case> {};

// Noise-free surfaces: every centre, and the tip node (from the last neck's axis), within
// 0.05 mm, though the start is millimetres and degrees off.
TEST_P(ChainFit, NoiseFreeSurfacesGiveTheCentres) {
  const auto [shape, distance] = GetParam();
  const ComponentGeometry g;
  const Nodes truth = chain_at(shape, distance, g);
  sim::SurfaceSampling s;
  s.seed = 5;
  const Cloud cloud = sim::sample_visible_surface(truth, g, s);
  const test::Soa pts(cloud);
  ChainState chain = perturbed(truth, g, 9);
  ASSERT_GT(max_error(chain.nodes(g.pitch), truth), 3e-3);  // the start is really off
  const ChainFitResult r = fit_chain(pts.view(), chain, g, {});
  EXPECT_LT(max_error(chain.nodes(g.pitch), truth), kNoiseFreeBand)
      << "mean " << mean_error(chain.nodes(g.pitch), truth) * 1e3 << " mm after "
      << r.iterations << " iterations";
  EXPECT_LT(r.rms, 1e-6);
  expect_pitch(chain, g);
}

// Axial noise of 0.4 mm (the SR300's sigma at these depths): the mean centre error stays
// under 0.5 mm, with no constant offset toward the camera.
TEST_P(ChainFit, NoisySurfacesStayUnbiased) {
  const auto [shape, distance] = GetParam();
  const ComponentGeometry g;
  const Nodes truth = chain_at(shape, distance, g);
  sim::SurfaceSampling s;
  s.noise_sigma = 0.4e-3;
  s.seed = 6;
  const test::Soa pts(sim::sample_visible_surface(truth, g, s));
  ChainState chain = perturbed(truth, g, 10);
  (void)fit_chain(pts.view(), chain, g, {});
  const Nodes fit = chain.nodes(g.pitch);
  EXPECT_LT(mean_error(fit, truth), kNoisyMeanBand);
  double along_ray = 0;  // signed: + away from the camera
  for (std::size_t k = 0; k < truth.size(); ++k) along_ray += (fit[k] - truth[k]).dot(truth[k].normalized());
  EXPECT_LT(std::abs(along_ray / static_cast<double>(truth.size())), 0.1e-3);
  expect_pitch(chain, g);
}

std::string case_name(const ::testing::TestParamInfo<Case>& info) {
  static const char* const kShapes[] = {"straight", "c", "s"};
  return std::string(kShapes[static_cast<int>(std::get<0>(info.param))]) + "_" +
         std::to_string(static_cast<int>(std::get<1>(info.param) * 100)) + "cm";
}

INSTANTIATE_TEST_SUITE_P(ShapesAndDistances, ChainFit,
                         ::testing::Combine(::testing::Values(sim::ChainShape::straight,
                                                              sim::ChainShape::c_shape,
                                                              sim::ChainShape::s_shape),
                                            ::testing::Values(0.4, 0.7, 1.0)),
                         case_name);

// Stray points near the link (a hand, flying pixels) weigh little: no centre moves more
// than 0.5 mm for 10% strays within 8 mm of the surface.
TEST(ChainFitRobust, StrayPointsPullLittle) {
  const ComponentGeometry g;
  const Nodes truth = test::test_chain(sim::ChainShape::c_shape);
  sim::SurfaceSampling s;
  s.seed = 7;
  Cloud cloud = sim::sample_visible_surface(truth, g, s);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-0.008, 0.008);
  const std::size_t strays = cloud.size() / 10;
  for (std::size_t i = 0; i < strays; ++i) {
    const std::size_t j = rng() % cloud.size();
    cloud.push_back(Eigen::Vector3d(cloud.xyz[3 * j] + u(rng), cloud.xyz[3 * j + 1] + u(rng),
                                    cloud.xyz[3 * j + 2] + u(rng)));
  }
  const test::Soa pts(cloud);
  ChainState chain = perturbed(truth, g, 11);
  (void)fit_chain(pts.view(), chain, g, {});
  EXPECT_LT(max_error(chain.nodes(g.pitch), truth), 0.5e-3);
}

// A hidden component has no points: it is carried by the chain (its axis stays where the
// start had it), and the rest still fit.
TEST(ChainFitRobust, HiddenComponentsAreCarried) {
  const ComponentGeometry g;
  const Nodes truth = test::test_chain(sim::ChainShape::straight);
  sim::SurfaceSampling s;
  s.hidden = {5, 6};
  const test::Soa pts(sim::sample_visible_surface(truth, g, s));
  ChainState chain = chain_from_nodes(truth, g);
  (void)fit_chain(pts.view(), chain, g, {});
  EXPECT_LT(max_error(chain.nodes(g.pitch), truth), kNoiseFreeBand);
}

TEST(ChainFitRobust, NearestSurfaceAndBadInput) {
  const ComponentGeometry g;
  const Nodes truth = test::test_chain(sim::ChainShape::straight);
  const ChainState chain = chain_from_nodes(truth, g);
  // A point on the far side of ball 3, 2 mm out.
  const Eigen::Vector3d p = truth[3] + (g.ball_radius + 0.002) * Eigen::Vector3d(0, 0, 1);
  const SurfaceHit h = nearest_surface(p, chain, g);
  EXPECT_EQ(h.component, 3);
  EXPECT_NEAR(h.distance, 0.002, 1e-12);
  ChainState wrong = chain;
  wrong.axis.pop_back();
  const test::Soa none(Cloud{});
  EXPECT_THROW((void)fit_chain(none.view(), wrong, g, {}), std::invalid_argument);
  ChainFitParams bad;
  bad.huber = 0;
  EXPECT_THROW((void)fit_chain(none.view(), wrong, g, bad), fields::FieldError);
}

}  // namespace
}  // namespace linksight
