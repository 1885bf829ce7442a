// chain_fit.hpp: the chain fitted to the surface points, centres without the surface bias.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <tuple>

#include "linksight/sim/synthetic_chain.hpp"
#include "linksight/tracker/chain_fit.hpp"
#include "linksight/tracker/opencl.hpp"
#include "linksight/tracker/tracker.hpp"
#include "test_support.hpp"

namespace linksight {
namespace {

constexpr double kNoiseFreeBand = 0.05e-3;  // [m]: issue 17's noise-free target
constexpr double kNoisyMeanBand = 0.5e-3;   // [m]: issue 17's sr300 target (mean)
constexpr double kPitchTolerance = 1e-9;    // [m]: issue 17 asks for 1e-6
// [m]: a noise-free fit's points off its surface. gcc's build reads 0.006-0.025 µm (about
// what float32 points leave), clang's 0.12 µm on the C-shaped link: the final step, within
// the fit's tolerance, lands a little differently.
constexpr double kNoiseFreeRms = 1e-6;

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
// RMS distance of every point to the chain's surface [m].
double surface_rms(const Cloud& cloud, const ChainState& chain, const ComponentGeometry& g) {
  double sum2 = 0;
  for (std::size_t i = 0; i < cloud.size(); ++i)
    sum2 += std::pow(nearest_surface(cloud.point(i), chain, g).distance, 2);
  return std::sqrt(sum2 / static_cast<double>(cloud.size()));
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
  // Converged onto the surface: the fitted chain's own RMS distance to the points (the
  // result's rms is the last accepted pass's, before the final step within the tolerance:
  // how small it is depends on the path the steps take, and it differs between compilers).
  EXPECT_LT(surface_rms(cloud, chain, g), kNoiseFreeRms) << "the last pass's rms " << r.rms;
  EXPECT_LT(r.rms, ChainFitParams{}.tolerance);
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

// ---- the chain-fit mode over frames (update_chain_fit.cpp) ----

// The test link moved rigidly: translated by `shift` [m] along x and turned by `turn`
// [rad] about the camera's y axis through its base.
Nodes moved(const Nodes& nodes, double shift, double turn) {
  const Eigen::Matrix3d R = Eigen::AngleAxisd(turn, Eigen::Vector3d::UnitY()).toRotationMatrix();
  Nodes out;
  for (const Eigen::Vector3d& q : nodes)
    out.push_back(nodes[0] + R * (q - nodes[0]) + Eigen::Vector3d(shift, 0, 0));
  return out;
}

Tracker chain_fit_tracker() {
  TrackerParams p;
  p.mode = parse_mode("chain-fit");
  return Tracker(p);
}

// Issue 17, part 3: a part hidden by something in front of it (here its points are simply
// gone) is carried by the chain and its last shape: while the visible half moves (3 mm
// and 0.4 deg per frame) the hidden half moves rigidly with it, and while the link is
// still the hidden half keeps its place.
TEST(ChainFitMode, HiddenPartMovesRigidlyWithWhatIsSeen) {
  // Measured: hidden nodes at most 1.11 mm off while the link moves (the tip node, 0.27 m
  // from the last seen ball, at frame 7) and at most 0.49 mm once it has stood for two
  // frames; issue 17's target for a moving link with a board over it is 10 mm.
  constexpr double kCarriedBand = 2.0e-3;  // [m]: hidden nodes while the link moves
  constexpr double kHeldBand = 1.0e-3;     // [m]: hidden nodes once it stands
  const ComponentGeometry g;
  const Nodes rest = test::test_chain(sim::ChainShape::c_shape);
  Tracker tracker = chain_fit_tracker();
  sim::SurfaceSampling s;
  s.noise_sigma = 0.4e-3;
  for (int f = 0; f < 16; ++f) {
    const int moving = std::min(f, 10);  // moves for 10 frames, then stands
    const Nodes truth = moved(rest, 0.003 * moving, 0.007 * moving);
    s.seed = static_cast<std::uint64_t>(20 + f);
    s.hidden = f < 3 ? std::vector<int>{} : std::vector<int>{6, 7, 8, 9, 10};
    const FrameResult r = tracker.step(sim::sample_visible_surface(truth, g, s));
    SCOPED_TRACE("frame " + std::to_string(f));
    for (std::size_t k = 0; k + 1 < r.nodes.size(); ++k)
      EXPECT_NEAR((r.nodes[k + 1] - r.nodes[k]).norm(), g.pitch, 1e-6);
    for (std::size_t k = 6; k < truth.size(); ++k)
      EXPECT_LT((r.nodes[k] - truth[k]).norm(), f > 12 ? kHeldBand : kCarriedBand)
          << "hidden node " << k;
    for (std::size_t k = 0; k < 6; ++k)
      EXPECT_LT((r.nodes[k] - truth[k]).norm(), kNoisyMeanBand) << "seen node " << k;
  }
}

// Stray points: a hand touching ball 5 (a dense patch on a 40 mm sphere whose surface
// meets the ball's), a mug 5 cm behind the link, and flying pixels trailing from the
// silhouette toward a background 0.3 m behind; none pulls a centre by more than 0.5 mm
// from where the clean cloud puts it.
TEST(ChainFitMode, AHandAMugAndFlyingPixelsPullNoCentre) {
  constexpr double kPullBand = 0.5e-3;  // [m]: issue 17
  const ComponentGeometry g;
  const Nodes truth = test::test_chain(sim::ChainShape::s_shape);
  std::mt19937_64 rng(17);
  std::normal_distribution<double> n01(0.0, 1.0);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const auto on_sphere = [&](const Eigen::Vector3d& c, double r) {
    Eigen::Vector3d d(n01(rng), n01(rng), n01(rng));
    return Eigen::Vector3d(c + r * d.normalized());
  };
  Tracker clean = chain_fit_tracker(), cluttered = chain_fit_tracker();
  for (int f = 0; f < 4; ++f) {
    sim::SurfaceSampling s;
    s.noise_sigma = 0.4e-3;
    s.seed = static_cast<std::uint64_t>(40 + f);
    const Cloud link = sim::sample_visible_surface(truth, g, s);
    Cloud dirty = link;
    // The hand: its near side (toward the camera), touching ball 5 from above.
    const Eigen::Vector3d up(0, -1, 0);
    const Eigen::Vector3d hand = truth[5] + (g.ball_radius + 0.040) * up;
    for (int i = 0; i < 600; ++i) {
      const Eigen::Vector3d q = on_sphere(hand, 0.040);
      if ((q - hand).dot(hand) < 0) dirty.push_back(q);  // the half facing the camera
    }
    // The mug: the front half of a 4 cm cylinder whose nearest side is 5 cm behind ball
    // 3's centre (3.5 cm behind the ball).
    for (int i = 0; i < 400; ++i) {
      const double a = M_PI * u01(rng), h = 0.08 * u01(rng);
      dirty.push_back(truth[3] + Eigen::Vector3d(0.04 * std::cos(a), -h, 0.09 - 0.04 * std::sin(a)));
    }
    // Flying pixels: 5% of the link's points slid back along their rays by 2-300 mm.
    for (std::size_t i = 0; i < link.size(); i += 20) {
      const Eigen::Vector3d p = link.point(i);
      dirty.push_back(p * (1.0 + (0.002 + 0.3 * u01(rng)) / p.norm()));
    }
    const FrameResult a = clean.step(link), b = cluttered.step(dirty);
    for (std::size_t k = 0; k < a.nodes.size(); ++k)
      EXPECT_LT((a.nodes[k] - b.nodes[k]).norm(), kPullBand) << "frame " << f << " node " << k;
  }
}

// The fit's passes give the same bits for any thread count (points summed in fixed blocks
// in a fixed order): 20k points (10 blocks), from a start millimetres off, with the
// association reused between searches.
TEST(ChainFitRobust, ThreadsGiveTheSerialBits) {
  const ComponentGeometry g;
  const Nodes truth = test::test_chain(sim::ChainShape::s_shape);
  sim::SurfaceSampling s;
  s.samples_per_ball = 3600;
  s.noise_sigma = 0.5e-3;
  s.seed = 12;
  const test::Soa pts(sim::sample_visible_surface(truth, g, s));
  ASSERT_GT(pts.x.size(), 3u * 2048u);
  ChainState serial = perturbed(truth, g, 13);
  const ChainFitResult a = fit_chain(pts.view(), serial, g, {}, 1);
  EXPECT_GT(a.passes, a.searches);  // some pass reused the association
  for (int threads : {2, 3, 4}) {
    ChainState parallel = perturbed(truth, g, 13);
    const ChainFitResult b = fit_chain(pts.view(), parallel, g, {}, threads);
    EXPECT_EQ(a.passes, b.passes) << threads << " threads";
    EXPECT_EQ(a.counts, b.counts) << threads << " threads";
    EXPECT_EQ(a.cost, b.cost) << threads << " threads";
    EXPECT_EQ(serial.c0, parallel.c0) << threads << " threads";
    EXPECT_EQ(serial.axis, parallel.axis) << threads << " threads";
  }
}

// Reusing a search while the chain stays within reassociate_m of it moves no centre by
// more than a hundredth of a millimetre against searching on every pass.
TEST(ChainFitRobust, ReusedAssociationGivesTheSearchedResult) {
  constexpr double kReuseBand = 0.01e-3;  // [m]
  const ComponentGeometry g;
  const Nodes truth = test::test_chain(sim::ChainShape::c_shape);
  sim::SurfaceSampling s;
  s.noise_sigma = 0.4e-3;
  s.seed = 14;
  const test::Soa pts(sim::sample_visible_surface(truth, g, s));
  ChainState reused = perturbed(truth, g, 15), searched = reused;
  const ChainFitResult a = fit_chain(pts.view(), reused, g, {});
  ChainFitParams every;
  every.reassociate = 0;
  const ChainFitResult b = fit_chain(pts.view(), searched, g, every);
  EXPECT_LT(a.searches, a.passes);
  EXPECT_EQ(b.searches, b.passes);
  EXPECT_LT(max_error(reused.nodes(g.pitch), searched.nodes(g.pitch)), kReuseBand);
}

// Coarse to fine (coarse_stride): converging on every 8th point and then taking one
// full pass's step gives the centres a fit on every point gives, within a third of the
// tolerance, with one pass over every point instead of several; the noise-free fit is as
// exact. A chain with a hidden component, and a cloud too small for the coarse stage,
// are fitted as without it.
TEST(ChainFitRobust, CoarseStageGivesTheFullFitsCentresInOneFullPass) {
  constexpr double kCoarseBand = 0.01e-3;  // [m]
  const ComponentGeometry g;
  const Nodes truth = test::test_chain(sim::ChainShape::s_shape);
  // The same start fitted with the coarse stage (the default) and without it.
  struct Pair {
    ChainState coarse, full;
    ChainFitResult a, b;
  };
  const auto fit_both = [&](const sim::SurfaceSampling& s, std::uint64_t start_seed,
                            bool with_shape) {
    const test::Soa pts(sim::sample_visible_surface(truth, g, s));
    Pair r;
    r.coarse = perturbed(truth, g, start_seed);
    r.full = r.coarse;
    const ChainState shape = r.coarse;
    const ChainState* prior = with_shape ? &shape : nullptr;
    ChainFitParams every;
    every.coarse_stride = 1;
    r.a = fit_chain(pts.view(), r.coarse, g, {}, 1, prior);
    r.b = fit_chain(pts.view(), r.full, g, every, 1, prior);
    return r;
  };
  for (const double noise : {0.0, 0.4e-3}) {
    SCOPED_TRACE("noise " + std::to_string(noise * 1e3) + " mm");
    sim::SurfaceSampling s;
    s.noise_sigma = noise;
    s.seed = 16;
    const Pair r = fit_both(s, 17, false);
    EXPECT_GT(r.a.coarse_passes, 0);
    EXPECT_EQ(r.a.passes - r.a.coarse_passes, 1) << "passes over every point";
    EXPECT_EQ(r.b.coarse_passes, 0);
    EXPECT_GT(r.b.passes, 2);
    EXPECT_LT(max_error(r.coarse.nodes(g.pitch), r.full.nodes(g.pitch)), kCoarseBand);
    if (noise == 0.0) {
      EXPECT_LT(max_error(r.coarse.nodes(g.pitch), truth), kNoiseFreeBand);
    }
    expect_pitch(r.coarse, g);
  }
  // A hidden half: the first coarse pass finds components without points, and the fit
  // goes on as one without the coarse stage, to the bit, one coarse pass later.
  {
    SCOPED_TRACE("hidden half");
    sim::SurfaceSampling s;
    s.noise_sigma = 0.4e-3;
    s.seed = 19;
    s.hidden = {6, 7, 8, 9, 10};
    const Pair r = fit_both(s, 20, true);
    EXPECT_EQ(r.a.coarse_passes, 1);
    EXPECT_EQ(r.a.passes, r.b.passes + 1);
    EXPECT_EQ(r.a.searches, r.b.searches + 1);
    EXPECT_EQ(r.coarse.c0, r.full.c0);
    EXPECT_EQ(r.coarse.axis, r.full.axis);
    EXPECT_EQ(r.a.counts, r.b.counts);
    EXPECT_EQ(r.a.cost, r.b.cost);
  }
  // One point fewer than the coarse stage needs.
  const auto few = static_cast<std::ptrdiff_t>(
      kCoarseMinPerComponent * static_cast<std::size_t>(g.count) *
          static_cast<std::size_t>(ChainFitParams{}.coarse_stride) - 1);
  const Nodes c_truth = test::test_chain(sim::ChainShape::c_shape);
  const test::Soa all(sim::sample_visible_surface(c_truth, g, {}));
  ASSERT_GT(static_cast<std::ptrdiff_t>(all.x.size()), few);
  const std::vector<float> x(all.x.begin(), all.x.begin() + few),
      y(all.y.begin(), all.y.begin() + few), z(all.z.begin(), all.z.begin() + few);
  ChainState chain = perturbed(c_truth, g, 18);
  const ChainFitResult r = fit_chain(PointsView{x, y, z}, chain, g, {});
  EXPECT_EQ(r.coarse_passes, 0);
}

// The largest connected cluster: the link, not a mug 3 cm from it; ties to the cluster of
// the lowest point index; bad input named.
TEST(ChainFitRobust, LargestClusterKeepsTheLinkAndDropsClutterApart) {
  const ComponentGeometry g;
  const Nodes truth = test::test_chain(sim::ChainShape::straight);
  Cloud cloud = sim::sample_visible_surface(truth, g, {});
  const std::size_t link = cloud.size();
  for (int i = 0; i < 300; ++i)  // a blob 3 cm beyond ball 10's far side
    cloud.push_back(truth[10] + Eigen::Vector3d(0.001 * (i % 10), 0.001 * (i / 10 % 10),
                                                g.ball_radius + 0.03 + 0.001 * (i / 100)));
  const test::Soa pts(cloud);
  const std::vector<std::size_t> keep = largest_cluster(pts.view(), g.neck_radius);
  ASSERT_EQ(keep.size(), link);
  EXPECT_EQ(keep.back(), link - 1);
  // Two equal clusters: the first point's.
  Cloud two;
  two.push_back(Eigen::Vector3d(0, 0, 1));
  two.push_back(Eigen::Vector3d(0.5, 0, 1));
  const test::Soa tp(two);
  EXPECT_EQ(largest_cluster(tp.view(), 0.01), std::vector<std::size_t>{0});
  EXPECT_THROW((void)largest_cluster(tp.view(), 0.0), std::invalid_argument);
  Cloud far;
  far.push_back(Eigen::Vector3d(0, 0, 200));
  const test::Soa fp(far);
  EXPECT_THROW((void)largest_cluster(fp.view(), 0.0001), std::invalid_argument);
}

// Loss (issue 17, part 5): the link jumps 0.2 m between frames, out of the fit's reach.
// The fit keeps no inlier, a fresh initialization explains the points, and the frame says
// so (init_reason misfit); the next frame tracks from there.
TEST(ChainFitMode, AJumpOutOfReachReinitializesOnMisfit) {
  const ComponentGeometry g;
  const Nodes rest = test::test_chain(sim::ChainShape::c_shape);
  Tracker tracker = chain_fit_tracker();
  sim::SurfaceSampling s;
  s.noise_sigma = 0.4e-3;
  std::vector<FrameResult> r;
  for (int f = 0; f < 4; ++f) {
    s.seed = static_cast<std::uint64_t>(60 + f);
    const Nodes truth = moved(rest, f >= 2 ? 0.2 : 0.0, 0.0);
    r.push_back(tracker.step(sim::sample_visible_surface(truth, g, s)));
    EXPECT_LT(mean_error(r.back().nodes, truth), kNoisyMeanBand) << "frame " << f;
  }
  EXPECT_EQ(r[0].init_reason, InitReason::first_frame);
  EXPECT_EQ(r[1].init_reason, InitReason::none);
  EXPECT_TRUE(r[2].reinit);
  EXPECT_EQ(r[2].init_reason, InitReason::misfit);
  EXPECT_EQ(r[3].init_reason, InitReason::none);
}

// Issue 17, part 4: a known base pose, 1 mm and 0.5° off (as a hand-eye calibration may
// be). The base half (balls 0-5, bent) is hidden from frame 3 on, and the link turns
// about the axis of its seen half (straight balls 6-10): the points show none of that
// turn, the base pose all of it. With the pose every node stays within the band; without
// it the hidden half stays where it was last seen.
TEST(ChainFitMode, ABasePoseHoldsTheChainWhenItsBaseEndIsHidden) {
  // Measured: with the pose every node within 0.58 mm (the hidden balls held where they
  // were last seen in the base frame; 2.25 mm without that hold, from the anchor alone);
  // without the pose the base node ends 18.8 mm off.
  constexpr double kWithBaseBand = 1.0e-3;  // [m]
  constexpr double kWithoutAtLeast = 8e-3;  // [m]: the turn the points cannot show
  const ComponentGeometry g;
  std::vector<double> bends(static_cast<std::size_t>(g.count - 1), 0.0);
  for (std::size_t k = 0; k < 5; ++k) bends[k] = 0.15;  // joints 1-5 bent, 6-10 straight
  Eigen::Isometry3d X_CB0 = Eigen::Isometry3d::Identity();
  X_CB0.translation() = Eigen::Vector3d(-0.22, -0.02, 0.6);
  X_CB0.linear() = Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitX()).toRotationMatrix();
  const Nodes rest = sim::chain_nodes(g, bends, X_CB0);
  const Eigen::Vector3d pivot = rest[6];
  const Eigen::Vector3d axis = (rest[11] - rest[6]).normalized();  // the seen half's
  Eigen::Isometry3d error = Eigen::Isometry3d::Identity();
  error.translation() = Eigen::Vector3d(0.0006, -0.0006, 0.0005);  // 1.0 mm
  error.linear() = Eigen::AngleAxisd(0.5 * M_PI / 180, Eigen::Vector3d(1, 1, 0).normalized())
                       .toRotationMatrix();
  TrackerParams p;
  p.mode = parse_mode("chain-fit");
  Tracker with(p), without(p);
  sim::SurfaceSampling s;
  s.noise_sigma = 0.4e-3;
  double worst_with = 0, last_without = 0;
  for (int f = 0; f < 14; ++f) {
    const int turning = std::max(0, std::min(f, 12) - 2);  // 0.02 rad a frame from frame 3
    Eigen::Isometry3d turn = Eigen::Isometry3d::Identity();
    turn.linear() = Eigen::AngleAxisd(0.02 * turning, axis).toRotationMatrix();
    turn.translation() = pivot - turn.linear() * pivot;
    const Eigen::Isometry3d X_CB = turn * X_CB0;
    const Nodes truth = sim::chain_nodes(g, bends, X_CB);
    s.seed = static_cast<std::uint64_t>(80 + f);
    s.hidden = f < 3 ? std::vector<int>{} : std::vector<int>{0, 1, 2, 3, 4, 5};
    const Cloud cloud = sim::sample_visible_surface(truth, g, s);
    const Eigen::Isometry3d prior = X_CB * error;
    const FrameResult a = with.step(cloud, &prior);
    const FrameResult b = without.step(cloud);
    SCOPED_TRACE("frame " + std::to_string(f));
    for (std::size_t k = 0; k + 1 < a.nodes.size(); ++k)
      EXPECT_NEAR((a.nodes[k + 1] - a.nodes[k]).norm(), g.pitch, 1e-6);
    for (std::size_t k = 0; k < truth.size(); ++k) {
      worst_with = std::max(worst_with, (a.nodes[k] - truth[k]).norm());
      EXPECT_LT((a.nodes[k] - truth[k]).norm(), kWithBaseBand) << "node " << k;
    }
    last_without = (b.nodes[0] - truth[0]).norm();
  }
  EXPECT_GT(last_without, kWithoutAtLeast) << "the points alone showed the turn";
  std::printf("base prior: worst node %.2f mm with the pose; base node %.1f mm off without\n",
              worst_with * 1e3, last_without * 1e3);
}

// The base anchors the components' indices (issue 17, part 3): a straight link whose base
// half is hidden from the first frame on shows five components; from the points alone
// they are some five of them (measured: every node three components off), with the base
// pose they are balls 6-10.
TEST(ChainFitMode, TheBaseAnchorsIndicesWhenTheBaseEndWasNeverSeen) {
  const ComponentGeometry g;
  const std::vector<double> straight(static_cast<std::size_t>(g.count - 1), 0.0);
  Eigen::Isometry3d X_CB = Eigen::Isometry3d::Identity();
  X_CB.translation() = Eigen::Vector3d(-0.25, 0.0, 0.6);
  const Nodes truth = sim::chain_nodes(g, straight, X_CB);
  sim::SurfaceSampling s;
  s.noise_sigma = 0.4e-3;
  s.hidden = {0, 1, 2, 3, 4, 5};
  TrackerParams p;
  p.mode = parse_mode("chain-fit");
  Tracker with(p), without(p);
  for (int f = 0; f < 3; ++f) {
    s.seed = static_cast<std::uint64_t>(95 + f);
    const Cloud cloud = sim::sample_visible_surface(truth, g, s);
    const FrameResult a = with.step(cloud, &X_CB);
    const FrameResult b = without.step(cloud);
    SCOPED_TRACE("frame " + std::to_string(f));
    EXPECT_LT(mean_error(a.nodes, truth), kNoisyMeanBand);
    EXPECT_GT(mean_error(b.nodes, truth), g.pitch) << "the points alone did place it";
  }
}

// With a base pose, ball 0 is the end at the base whichever way the cloud's extent would
// order the chain: the same straight link, based at either end.
TEST(ChainFitMode, TheBaseSaysWhichEndIsBallZero) {
  const ComponentGeometry g;
  const std::vector<double> straight(static_cast<std::size_t>(g.count - 1), 0.0);
  for (const double turn : {0.0, M_PI}) {
    SCOPED_TRACE("base turned by " + std::to_string(turn));
    Eigen::Isometry3d X_CB = Eigen::Isometry3d::Identity();
    X_CB.translation() = Eigen::Vector3d(turn == 0.0 ? -0.25 : 0.25, 0.0, 0.6);
    X_CB.linear() = Eigen::AngleAxisd(turn, Eigen::Vector3d::UnitY()).toRotationMatrix();
    const Nodes truth = sim::chain_nodes(g, straight, X_CB);
    sim::SurfaceSampling s;
    s.noise_sigma = 0.4e-3;
    s.seed = 90;
    TrackerParams p;
    p.mode = parse_mode("chain-fit");
    Tracker tracker(p);
    const FrameResult r = tracker.step(sim::sample_visible_surface(truth, g, s), &X_CB);
    EXPECT_LT(mean_error(r.nodes, truth), kNoisyMeanBand);
    EXPECT_LT((r.nodes[0] - X_CB.translation()).norm(), 1e-3);
  }
}

// A base pose that is not a finite rigid transform is refused; paper modes take a pose
// and ignore it (their output is the same bits without one).
TEST(ChainFitMode, ABasePoseMustBeRigidAndPaperModesIgnoreIt) {
  const ComponentGeometry g;
  const Nodes truth = test::test_chain(sim::ChainShape::c_shape);
  sim::SurfaceSampling s;
  s.seed = 91;
  const Cloud cloud = sim::sample_visible_surface(truth, g, s);
  Tracker tracker = chain_fit_tracker();
  Eigen::Isometry3d scaled = Eigen::Isometry3d::Identity();
  scaled.linear() *= 1.01;
  EXPECT_THROW((void)tracker.step(cloud, &scaled), std::invalid_argument);
  Eigen::Isometry3d nan = Eigen::Isometry3d::Identity();
  nan.translation().x() = std::nan("");
  EXPECT_THROW((void)tracker.step(cloud, &nan), std::invalid_argument);
  Eigen::Isometry3d mirrored = Eigen::Isometry3d::Identity();
  mirrored.linear()(2, 2) = -1;
  EXPECT_THROW((void)tracker.step(cloud, &mirrored), std::invalid_argument);
  TrackerParams p = test::paper_params();
  Tracker a(p), b(p);
  const Eigen::Isometry3d X_CB = Eigen::Isometry3d::Identity();
  EXPECT_EQ(a.step(cloud, &X_CB).nodes, b.step(cloud).nodes);
}

// fit_chain refuses an anchor it cannot weigh.
TEST(ChainFit, AnAnchorNeedsAUnitAxisAndPositiveSigmas) {
  const ComponentGeometry g;
  const Nodes truth = test::test_chain(sim::ChainShape::c_shape);
  const Cloud cloud = sim::sample_visible_surface(truth, g, {});
  const test::Soa pts(cloud);
  ChainState chain = chain_from_nodes(truth, g);
  ChainAnchor a;
  a.c0 = truth[0];
  a.axis0 = chain.axis[0];
  EXPECT_NO_THROW((void)fit_chain(pts.view(), chain, g, {}, 1, nullptr, &a));
  ChainAnchor zero = a;
  zero.sigma_m = 0;
  EXPECT_THROW((void)fit_chain(pts.view(), chain, g, {}, 1, nullptr, &zero), std::invalid_argument);
  ChainAnchor long_axis = a;
  long_axis.axis0 *= 2;
  EXPECT_THROW((void)fit_chain(pts.view(), chain, g, {}, 1, nullptr, &long_axis),
               std::invalid_argument);
}

// Free space (issue 17, part 3). A straight link 0.6 m in front of the camera; from frame
// 3 its tip half (balls 6-10) shows no points. The depth image of a 640x480 pinhole camera
// sees a wall 1.2 m away and, where `occluder` says, a board 0.3 m away.
struct FreeSpaceScene {
  static constexpr int kWidth = 640, kHeight = 480;
  static constexpr double kF = 473, kCx = 320, kCy = 240;
  std::vector<float> depth = std::vector<float>(kWidth * kHeight, 1.2F);
  template <class Occluded>
  explicit FreeSpaceScene(Occluded occluded) {
    for (int v = 0; v < kHeight; ++v)
      for (int u = 0; u < kWidth; ++u)
        if (occluded(u, v)) depth[static_cast<std::size_t>(v * kWidth + u)] = 0.3F;
  }
  [[nodiscard]] DepthView view() const { return {kWidth, kHeight, depth, kF, kF, kCx, kCy}; }
};

// The link, straight along the camera's x axis at y = 0, z = 0.6 m; `tip_bend` turns the
// components from ball 6 on in the image plane (negative: up, toward -y).
Nodes free_space_chain(double tip_bend) {
  const ComponentGeometry g;
  std::vector<double> bends(static_cast<std::size_t>(g.count - 1), 0.0);
  bends[5] = tip_bend;
  Eigen::Isometry3d X_CB = Eigen::Isometry3d::Identity();
  X_CB.translation() = Eigen::Vector3d(-0.22, 0.0, 0.6);
  return sim::chain_nodes(g, bends, X_CB);
}

// Tracks 9 frames: 0-2 the straight link in full; from 3 on `truth` with the tip hidden,
// with the depth image or without. Returns the last frame's nodes.
Nodes track_hidden_tip(const Nodes& truth, const DepthView* depth) {
  const ComponentGeometry g;
  Tracker tracker = chain_fit_tracker();
  sim::SurfaceSampling s;
  s.noise_sigma = 0.4e-3;
  FrameResult r;
  for (int f = 0; f < 9; ++f) {
    s.seed = static_cast<std::uint64_t>(120 + f);
    s.hidden = f < 3 ? std::vector<int>{} : std::vector<int>{6, 7, 8, 9, 10};
    const Nodes& now = f < 3 ? free_space_chain(0.0) : truth;
    r = tracker.step(sim::sample_visible_surface(now, g, s), nullptr, f < 3 ? nullptr : depth);
  }
  return r.nodes;
}

// Pixel column and row of a point of the link's plane (z = 0.6 m).
int column_of(double x) { return static_cast<int>(FreeSpaceScene::kCx + FreeSpaceScene::kF * x / 0.6); }
int row_of(double y) { return static_cast<int>(FreeSpaceScene::kCy + FreeSpaceScene::kF * y / 0.6); }

// A hidden tip with a board in front of all of it says nothing against its place: the
// depth image changes no bit of the fit.
TEST(ChainFitFreeSpace, AHiddenTipWithANearerSurfaceInFrontKeepsItsPlace) {
  const int board = column_of(0.025);  // from between balls 5 and 6 on
  const FreeSpaceScene scene([&](int u, int /*v*/) { return u >= board; });
  const DepthView depth = scene.view();
  const Nodes truth = free_space_chain(0.0);
  const Nodes with = track_hidden_tip(truth, &depth);
  EXPECT_EQ(with, track_hidden_tip(truth, nullptr));
  EXPECT_LT(mean_error(with, truth), kNoisyMeanBand);
}

// The tip was turned up (0.25 rad at ball 6) behind a board, and the points show none of
// it. The board covers ball 6 and, beyond it, the image above y = 4.5 mm: all of where the
// tip is, but not the lower edge of where it was. Held in its last shape, the tip would
// lie where the camera sees the wall through it: free space. With the depth image the fit
// moves balls 7-10 up, out of most of it; without it they stay on the straight line.
TEST(ChainFitFreeSpace, AHiddenTipInObservedFreeSpaceMoves) {
  // Measured: balls 7-10 end 5.8-18 mm up (clear of the wall's rays at 4.5 mm - r = -10.5
  // mm but for ball 7's lowest 5 mm: a ray near a ball's rim pushes little, and the shape
  // prior holds the bend), the tip node 33.8 mm from the truth against 56.1 mm without.
  constexpr double kMovedUp = -0.005;  // [m]: every hidden ball's centre above this
  const ComponentGeometry g;
  const int ball6_end = column_of(0.05 + g.ball_radius) + 1;
  const int low = row_of(0.016), high = row_of(0.0045);
  const int board = column_of(0.025);
  const FreeSpaceScene scene(
      [&](int u, int v) { return u >= board && (u <= ball6_end ? v <= low : v <= high); });
  const DepthView depth = scene.view();
  const Nodes truth = free_space_chain(-0.25);
  const Nodes with = track_hidden_tip(truth, &depth);
  const Nodes without = track_hidden_tip(truth, nullptr);
  for (int k = 7; k <= 10; ++k) {
    SCOPED_TRACE("ball " + std::to_string(k));
    EXPECT_NEAR(without[k].y(), 0.0, 2e-3) << "without the depth image the tip is held";
    EXPECT_LT(with[k].y(), kMovedUp) << "did not move out of the seen free space";
  }
  EXPECT_LT((with[11] - truth[11]).norm(), 0.7 * (without[11] - truth[11]).norm());
  for (std::size_t k = 0; k + 1 < with.size(); ++k)
    EXPECT_NEAR((with[k + 1] - with[k]).norm(), g.pitch, 1e-6);
  std::printf("free space: balls 7-10 at y = %.1f %.1f %.1f %.1f mm; tip node %.1f mm from the "
              "truth with the depth image, %.1f without\n",
              with[7].y() * 1e3, with[8].y() * 1e3, with[9].y() * 1e3, with[10].y() * 1e3,
              (with[11] - truth[11]).norm() * 1e3, (without[11] - truth[11]).norm() * 1e3);
}

// Issue 17, part 7: every back end gives chain-fit the serial reference's bits, frame by
// frame, through motion, a hidden half, stray points and a jump that re-initializes. On
// OpenCL the passes run as kernels (chain.cl) when the device has double precision.
class ChainFitBackends : public ::testing::TestWithParam<test::BackendCase> {};

TEST_P(ChainFitBackends, GiveTheSerialBits) {
  const test::BackendCase c = GetParam();
  LINKSIGHT_SKIP_IF_UNBUILT(c);
  if (c.kind == BackendKind::opencl) {
    const std::unique_ptr<Backend> backend = test::make(c);
    bool capable = false;
    for (const OpenCLDevice& d : opencl_devices())
      capable = capable || (d.fp64 && d.fp32_rounded_sqrt);
    // PoCL (CI) has double precision and a correctly rounded float square root: the kernels
    // must be the ones under test.
    if (capable) {
      EXPECT_NE(backend->chain_pass_device(), nullptr);
    }
  }
  const ComponentGeometry g;
  const Nodes rest = test::test_chain(sim::ChainShape::s_shape);
  TrackerParams p;
  p.mode = parse_mode("chain-fit");
  Tracker reference(p);
  p.backend = c.kind;
  p.threads = 2;
  p.opencl.accumulation = c.accumulation;
  Tracker tracker(p);
  sim::SurfaceSampling s;
  s.noise_sigma = 0.4e-3;
  // The base pose (test::test_chain's) moved with the link, and a depth image: a wall
  // 1.2 m away seen through where the hidden half is held (free-space rays on components
  // without points, added on the host to the device's sums).
  const FreeSpaceScene wall([](int /*u*/, int /*v*/) { return false; });
  const DepthView depth = wall.view();
  Eigen::Isometry3d X_CB0 = Eigen::Isometry3d::Identity();
  X_CB0.translation() = rest[0];
  X_CB0.linear() = Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitX()).toRotationMatrix();
  for (int f = 0; f < 10; ++f) {
    s.seed = static_cast<std::uint64_t>(100 + f);
    s.hidden = f >= 3 && f < 6 ? std::vector<int>{6, 7, 8, 9, 10} : std::vector<int>{};
    const double shift = f >= 8 ? 0.2 : 0.004 * f, turn = 0.005 * f;
    const Nodes truth = moved(rest, shift, turn);
    Eigen::Isometry3d X_CB = X_CB0;  // as moved() moves the nodes
    X_CB.linear() = Eigen::AngleAxisd(turn, Eigen::Vector3d::UnitY()) * X_CB0.linear();
    X_CB.translation() = rest[0] + Eigen::Vector3d(shift, 0, 0);
    Cloud cloud = sim::sample_visible_surface(truth, g, s);
    for (int i = 0; i < 30; ++i)  // strays 5 cm behind the link
      cloud.push_back(truth[5] + Eigen::Vector3d(0.001 * i, 0.0005 * i, 0.05));
    // No pose on the jump's frame: the base's move would predict it; without, the fit
    // loses the points and re-initializes (misfit).
    const Eigen::Isometry3d* pose = f == 8 ? nullptr : &X_CB;
    const FrameResult a = reference.step(cloud, pose, &depth);
    const FrameResult b = tracker.step(cloud, pose, &depth);
    SCOPED_TRACE("frame " + std::to_string(f));
    EXPECT_EQ(a.nodes, b.nodes);
    EXPECT_EQ(a.counts, b.counts);
    EXPECT_EQ(a.iterations, b.iterations);
    EXPECT_EQ(a.init_reason, b.init_reason);
    EXPECT_EQ(b.init_reason, f == 0   ? InitReason::first_frame
                             : f == 8 ? InitReason::misfit
                                      : InitReason::none);
    EXPECT_LT(mean_error(b.nodes, truth), kNoisyMeanBand);
  }
}

INSTANTIATE_TEST_SUITE_P(OtherBackends, ChainFitBackends,
                         ::testing::ValuesIn(test::other_backends()), test::backend_name);

}  // namespace
}  // namespace linksight
