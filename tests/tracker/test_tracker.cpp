// The tracker on synthetic chains with truth, parameterized over back ends.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "linksight/tracker/tracker.hpp"
#include "test_support.hpp"

namespace linksight {
namespace {

using sim::ChainShape;

struct Errors {
  double mean = 0, max = 0;
  double toward_camera =
      0;               // mean of the error component along the line of sight toward the camera
  double lateral = 0;  // mean norm of the rest
  int order_errors = 0;
};

// Compares the first `balls` nodes with the true ball centres.
Errors measure(const Nodes& est, const Nodes& truth, int balls = 11) {
  Errors e;
  for (int j = 0; j < balls; ++j) {
    const Eigen::Vector3d d = est[j] - truth[j];
    const Eigen::Vector3d to_cam = -truth[j].normalized();
    e.mean += d.norm() / balls;
    e.max = std::max(e.max, d.norm());
    e.toward_camera += d.dot(to_cam) / balls;
    e.lateral += (d - d.dot(to_cam) * to_cam).norm() / balls;
    int nearest = 0;
    for (int k = 1; k < balls; ++k) {
      if ((est[j] - truth[k]).norm() < (est[j] - truth[nearest]).norm()) nearest = k;
    }
    e.order_errors += nearest != j;
  }
  return e;
}

Cloud chain_cloud(const Nodes& truth, std::uint64_t seed, bool necks, double noise,
                  std::vector<int> hidden = {}) {
  sim::SurfaceSampling s;
  s.necks = necks;
  s.noise_sigma = noise;
  s.seed = seed;
  s.hidden = std::move(hidden);
  return sim::sample_visible_surface(truth, {}, s);
}

class TrackerShapes : public ::testing::TestWithParam<std::tuple<test::BackendCase, ChainShape>> {
 protected:
  void SetUp() override { LINKSIGHT_SKIP_IF_UNBUILT(std::get<0>(GetParam())); }
  TrackerParams params(int nodes) const {
    TrackerParams p = test::params_for(std::get<0>(GetParam()));
    p.nodes = nodes;
    p.policy.lsq_init.method = InitMethod::pca;
    return p;
  }
};

// 11 spheres seen from one side, 11 nodes. The mean of a visible hemisphere lies r/2
// in front of the centre, so paper mode (Eq. 12) is biased toward the camera by about
// r/2 = 7.5 mm. Measured (1 mm noise, all shapes, both back ends): 7.6-7.7 mm toward the
// camera, 0.4-0.5 mm lateral, max 8.05 mm; the biased nodes score 3.6-3.7 mm on the
// SDF metric, the paper's "< 4 mm" range, although every node is 7.7 mm off.
TEST_P(TrackerShapes, SpheresOnlyOrderAndMeasuredBias) {
  const Nodes truth = test::test_chain(std::get<1>(GetParam()));
  Tracker tracker(params(11));
  for (int f = 0; f < 3; ++f) {
    const FrameResult r = tracker.step(chain_cloud(truth, 10 + f, false, 0.001));
    ASSERT_FALSE(r.lost);
    EXPECT_EQ(r.init_reason, f == 0 ? InitReason::first_frame : InitReason::none);
    EXPECT_EQ(r.iterations, 4);
    const Errors e = measure(r.nodes, truth);
    EXPECT_EQ(e.order_errors, 0) << "frame " << f;
    EXPECT_GT(e.toward_camera, 0.0070) << "frame " << f;
    EXPECT_LT(e.toward_camera, 0.0084) << "frame " << f;
    EXPECT_LT(e.lateral, 0.0010) << "frame " << f;
    EXPECT_LT(e.max, 0.0090) << "frame " << f;
    EXPECT_GT(r.sdf_error, 0.0030) << "frame " << f;
    EXPECT_LT(r.sdf_error, 0.0045) << "frame " << f;
  }
}

// The default: 12 nodes (M+1, Eq. 1) on 11 components with necks; node 11 lies on the
// last component's axis. Measured: ball nodes in order, mean error 8.1-8.5 mm (7.9-8.1
// toward the camera, 1.0-1.7 lateral), node 11 7.8-10.9 mm beyond the last ball, SDF
// error 3.1-3.3 mm.
TEST_P(TrackerShapes, FullComponentsTwelveNodesInOrder) {
  const Nodes truth = test::test_chain(std::get<1>(GetParam()));
  Tracker tracker(params(12));
  for (int f = 0; f < 3; ++f) {
    const FrameResult r = tracker.step(chain_cloud(truth, 20 + f, true, 0.001));
    ASSERT_FALSE(r.lost);
    ASSERT_EQ(r.nodes.size(), 12u);
    const Errors e = measure(r.nodes, truth);
    EXPECT_EQ(e.order_errors, 0);
    EXPECT_LT(e.mean, 0.0095);
    EXPECT_LT(e.lateral, 0.0025);
    // The last node lies beyond the last ball, along its axis.
    const Eigen::Vector3d axis = (truth[11] - truth[10]).normalized();
    EXPECT_GT((r.nodes[11] - truth[10]).dot(axis), 0.005);  // measured 7-10 mm
    EXPECT_LT(r.sdf_error, 0.004);                          // the paper reports < 4 mm
  }
}

std::string shape_case_name(const ::testing::TestParamInfo<TrackerShapes::ParamType>& p) {
  static const char* const kShape[] = {"straight", "C", "S"};
  return test::case_name(std::get<0>(p.param)) + "_" +
         kShape[static_cast<int>(std::get<1>(p.param))];
}

INSTANTIATE_TEST_SUITE_P(BackendsAndShapes, TrackerShapes,
                         ::testing::Combine(::testing::ValuesIn(test::all_backends()),
                                            ::testing::Values(ChainShape::straight,
                                                              ChainShape::c_shape,
                                                              ChainShape::s_shape)),
                         shape_case_name);

// Eq. 9's form samples at constant x. For moderate bends seen broadside that is enough
// for the SOM to converge in order.
TEST(Tracker, PaperInitConvergesOnBroadsideShapes) {
  for (ChainShape shape : {ChainShape::straight, ChainShape::c_shape, ChainShape::s_shape}) {
    const Nodes truth = test::test_chain(shape, 0.1);
    TrackerParams p = test::paper_params();
    p.nodes = 11;
    p.policy.lsq_init.method = InitMethod::paper;
    Tracker tracker(p);
    FrameResult r;
    for (int f = 0; f < 4; ++f) r = tracker.step(chain_cloud(truth, 50 + f, false, 0.001));
    EXPECT_EQ(measure(r.nodes, truth).order_errors, 0) << static_cast<int>(shape);
    EXPECT_LT(measure(r.nodes, truth).lateral, 0.0025) << static_cast<int>(shape);
  }
}

// Where the link runs parallel to camera y (hanging, or the tip of an 86° C), y = a(x)
// is no function: the paper's init leaves the SOM in a wrong local minimum (measured:
// 167 mm mean error with 9 nodes out of order when hanging; 28 mm with 6 on the C).
// The principal-axis init tracks both (7.7 mm, the r/2 bias, in order).
TEST(Tracker, PaperInitFailsWhereTheLinkRunsAlongCameraYAndPcaDoesNot) {
  const std::vector<Nodes> cases = {test::hanging_chain(),
                                    test::test_chain(ChainShape::c_shape, 0.15)};
  for (std::size_t c = 0; c < cases.size(); ++c) {
    const Nodes& truth = cases[c];
    for (InitMethod init : {InitMethod::paper, InitMethod::pca}) {
      TrackerParams p = test::paper_params();
      p.nodes = 11;
      p.policy.lsq_init.method = init;
      Tracker tracker(p);
      FrameResult r;
      for (int f = 0; f < 4; ++f) r = tracker.step(chain_cloud(truth, 60 + f, false, 0.001));
      const Errors e = measure(r.nodes, truth);
      if (init == InitMethod::pca) {
        EXPECT_EQ(e.order_errors, 0) << "case " << c;
        EXPECT_LT(e.mean, 0.009) << "case " << c;
      } else {
        EXPECT_GE(e.order_errors, 5) << "case " << c;
        EXPECT_GT(e.mean, 0.020) << "case " << c;
      }
    }
  }
}

class TrackerBackends : public ::testing::TestWithParam<test::BackendCase> {
 protected:
  void SetUp() override { LINKSIGHT_SKIP_IF_UNBUILT(GetParam()); }
  TrackerParams params(int nodes = 11) const {
    TrackerParams p = test::params_for(GetParam());
    p.nodes = nodes;
    return p;
  }
};

// Sec. IV.C: two middle spheres vanish (occlusion) for five frames, then return.
TEST_P(TrackerBackends, ReinitFiresOnEmptyNeighbourhoodAndTrackingRecovers) {
  const Nodes truth = test::test_chain(ChainShape::c_shape);
  Tracker tracker(params());
  double baseline = 0;
  for (int f = 0; f < 15; ++f) {
    const bool hide = f >= 5 && f < 10;
    const FrameResult r = tracker.step(chain_cloud(
        truth, 30 + f, false, 0.001, hide ? std::vector<int>{4, 5} : std::vector<int>{}));
    ASSERT_FALSE(r.lost);
    const Errors e = measure(r.nodes, truth);
    if (f < 5) {
      EXPECT_FALSE(r.reinit) << "frame " << f;
      baseline = std::max(baseline, e.mean);
    } else if (hide) {
      EXPECT_TRUE(r.reinit) << "frame " << f;
      EXPECT_EQ(r.init_reason, InitReason::empty_neighbourhood);
      EXPECT_TRUE(r.reinit_node == 4 || r.reinit_node == 5) << r.reinit_node;
      EXPECT_EQ(r.iterations, 1 + tracker.params().iterations);
      EXPECT_EQ(e.order_errors, 0) << "frame " << f;
    } else {
      // Back in the first full frame: no re-initialization, error at the baseline.
      EXPECT_FALSE(r.reinit) << "frame " << f;
      EXPECT_EQ(e.order_errors, 0) << "frame " << f;
      EXPECT_LT(e.mean, baseline + 0.001) << "frame " << f;
    }
  }
}

TEST_P(TrackerBackends, AcceleratedSomNeverReinitializes) {
  const Nodes truth = test::test_chain(ChainShape::c_shape);
  TrackerParams p = params();
  p.mode = parse_mode("accelerated-som");
  Tracker tracker(p);
  FrameResult before;
  for (int f = 0; f < 8; ++f) {
    const bool hide = f >= 4;
    const FrameResult r = tracker.step(chain_cloud(
        truth, 40 + f, false, 0.001, hide ? std::vector<int>{4, 5} : std::vector<int>{}));
    EXPECT_FALSE(r.reinit);
    if (hide) {
      EXPECT_EQ(r.counts[4], 0);
      EXPECT_EQ(r.nodes[4], before.nodes[4]);  // an empty neighbourhood leaves the node alone
    }
    before = r;
  }
}

// The baseline's weakness the paper names: "the result depends heavily on the initial
// value". Random-sample init has no order, and nothing restores it (measured on the demo
// motion, 90 frames: 10 of 11 nodes out of order in every frame, 123-162 mm mean error
// depending on the seed). Straight-line init is as good as LSQ on this benign motion
// (8.2 mm); the paper's "accumulation for moving link" is left to the fast-motion scenes.
TEST_P(TrackerBackends, AcceleratedSomRandomInitNeverFindsTheOrder) {
  const ComponentGeometry g;
  std::vector<Nodes> last;
  for (std::uint64_t seed : {1u, 2u}) {
    TrackerParams p = params(12);
    p.mode = parse_mode("accelerated-som");
    p.policy.som_init.method = SomInit::random_sample;
    p.policy.som_init.seed = seed;
    Tracker tracker(p);
    FrameResult r;
    for (int f = 0; f < 20; ++f) {
      sim::SurfaceSampling s;
      s.noise_sigma = 0.001;
      s.seed = 100 + f;
      r = tracker.step(sim::sample_visible_surface(sim::demo_nodes(g, f, 30), g, s));
    }
    const Errors e = measure(r.nodes, sim::demo_nodes(g, 19, 30));
    EXPECT_GE(e.order_errors, 5) << "seed " << seed;
    EXPECT_GT(e.mean, 0.050) << "seed " << seed;
    last.push_back(r.nodes);
  }
  EXPECT_NE(last[0], last[1]);  // the outcome depends on the draw
}

// paper-centred runs the paper's SOM unchanged (same associations, same internal nodes,
// frame after frame) and moves only its output: each node 2/3 r further from the camera
// along its own viewing ray. Its accuracy on rendered frames is tested in tests/sim.
TEST_P(TrackerBackends, PaperCentredIsPaperMovedAlongEachViewingRay) {
  const Nodes truth = test::test_chain(ChainShape::c_shape);
  TrackerParams p = test::params_for(GetParam());
  Tracker paper(p);
  p.mode = parse_mode("paper-centred");
  Tracker centred(p);
  const double offset = kCentreOffset * p.geometry.ball_radius;
  EXPECT_NEAR(offset, 0.010, 1e-12);
  for (int f = 0; f < 3; ++f) {
    const Cloud cloud = chain_cloud(truth, 40 + f, true, 0.001);
    const FrameResult a = paper.step(cloud);
    const FrameResult b = centred.step(cloud);
    ASSERT_FALSE(b.lost);
    EXPECT_EQ(a.counts, b.counts) << "frame " << f;
    EXPECT_EQ(a.init_reason, b.init_reason) << "frame " << f;
    const auto la = paper.last_association(), lb = centred.last_association();
    ASSERT_EQ(la.size(), lb.size());
    EXPECT_TRUE(std::equal(la.begin(), la.end(), lb.begin())) << "frame " << f;
    ASSERT_EQ(a.nodes.size(), b.nodes.size());
    for (std::size_t j = 0; j < a.nodes.size(); ++j) {
      const Eigen::Vector3d ray = a.nodes[j].normalized();
      const Eigen::Vector3d moved = b.nodes[j] - a.nodes[j];
      EXPECT_NEAR(moved.dot(ray), offset, 1e-12) << "frame " << f << " node " << j;
      EXPECT_NEAR((moved - moved.dot(ray) * ray).norm(), 0.0, 1e-12) << "node " << j;
    }
    // The SDF metric scores the output: centres fit the component model better than
    // surface means.
    EXPECT_LT(b.sdf_error, a.sdf_error) << "frame " << f;
  }
  // A lost frame repeats the last output, still moved.
  const FrameResult lost = centred.step(Cloud{});
  ASSERT_TRUE(lost.lost);
  const FrameResult last_paper = paper.step(Cloud{});
  for (std::size_t j = 0; j < lost.nodes.size(); ++j)
    EXPECT_NEAR((lost.nodes[j] - last_paper.nodes[j]).norm(), offset, 1e-12);
}

TEST_P(TrackerBackends, LostFramesReportWhyAndKeepTheState) {
  const Nodes truth = test::test_chain(ChainShape::straight);
  Tracker tracker(params());
  const FrameResult first = tracker.step(chain_cloud(truth, 1, false, 0.0));
  ASSERT_FALSE(first.lost);

  const FrameResult empty = tracker.step(Cloud{});
  EXPECT_TRUE(empty.lost);
  EXPECT_EQ(empty.lost_reason, LostReason::empty_cloud);
  EXPECT_TRUE(std::isnan(empty.sdf_error));
  EXPECT_EQ(empty.nodes, first.nodes);

  Cloud nan_cloud;
  for (int i = 0; i < 20; ++i) nan_cloud.push_back(NAN, 0.f, INFINITY);
  const FrameResult nan = tracker.step(nan_cloud);
  EXPECT_EQ(nan.lost_reason, LostReason::all_non_finite);
  EXPECT_EQ(nan.n_non_finite, 20u);

  Cloud few;
  for (int i = 0; i < 5; ++i) few.push_back(truth[i]);
  const FrameResult too_few = tracker.step(few);
  EXPECT_EQ(too_few.lost_reason, LostReason::too_few_points);
  EXPECT_EQ(too_few.n_points, 5u);

  // The next good frame continues from the last good output.
  const FrameResult next = tracker.step(chain_cloud(truth, 2, false, 0.0));
  EXPECT_FALSE(next.lost);
  EXPECT_EQ(next.init_reason, InitReason::none);
}

TEST_P(TrackerBackends, NonFinitePointsAreDroppedAndCounted) {
  const Nodes truth = test::test_chain(ChainShape::s_shape);
  const Cloud clean = chain_cloud(truth, 3, false, 0.001);
  Cloud dirty;
  for (std::size_t i = 0; i < clean.size(); ++i) {
    if (i % 500 == 0) dirty.push_back(NAN, 1.f, 1.f);
    dirty.push_back(clean.point(i));
  }
  Tracker a(params()), b(params());
  const FrameResult ra = a.step(clean), rb = b.step(dirty);
  EXPECT_EQ(rb.n_non_finite, (clean.size() + 499) / 500);
  EXPECT_EQ(rb.n_points, clean.size());
  EXPECT_EQ(ra.nodes, rb.nodes);
}

// Beyond 100 m a coordinate could overflow the fixed-point sums: dropped and counted.
TEST_P(TrackerBackends, PointsBeyondTheRangeAreDroppedAndCounted) {
  const Cloud clean = chain_cloud(test::test_chain(ChainShape::c_shape), 4, false, 0.001);
  Cloud far = clean;
  far.push_back(3e9f, 0.f, 1.f);
  far.push_back(0.f, -150.f, 1.f);
  Tracker a(params()), b(params());
  const FrameResult ra = a.step(clean), rb = b.step(far);
  EXPECT_EQ(rb.n_out_of_range, 2u);
  EXPECT_EQ(rb.n_non_finite, 0u);
  EXPECT_EQ(ra.nodes, rb.nodes);
  Cloud only_far;
  for (int i = 0; i < 20; ++i) only_far.push_back(1000.f, 0.f, 1.f);
  const FrameResult lost = b.step(only_far);
  EXPECT_TRUE(lost.lost);
  EXPECT_EQ(lost.lost_reason, LostReason::too_few_points);
  EXPECT_EQ(lost.n_out_of_range, 20u);
}

TEST_P(TrackerBackends, ResetStartsOverAndToleranceStopsEarly) {
  const Nodes truth = test::test_chain(ChainShape::c_shape);
  TrackerParams p = params();
  p.tolerance = 0.0005;
  Tracker tracker(p);
  (void)tracker.step(chain_cloud(truth, 5, false, 0.0));
  const FrameResult still = tracker.step(chain_cloud(truth, 5, false, 0.0));
  EXPECT_LT(still.iterations, p.iterations);  // already converged on the same cloud
  tracker.reset();
  EXPECT_EQ(tracker.step(chain_cloud(truth, 5, false, 0.0)).init_reason, InitReason::first_frame);
}

INSTANTIATE_TEST_SUITE_P(Backends, TrackerBackends, ::testing::ValuesIn(test::all_backends()),
                         test::backend_name);

TEST(TrackerParams, ValidateNamesFieldAndValue) {
  auto message = [](const TrackerParams& p) {
    try {
      Tracker t(p);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  TrackerParams p;
  p.nodes = 1;
  EXPECT_EQ(message(p), "tracker.nodes = 1: must be in [2, 1000]");
  p = {};
  p.iterations = 0;
  EXPECT_EQ(message(p), "tracker.iterations = 0: must be in [1, 1000]");
  p = {};
  p.threads = -2;
  EXPECT_EQ(message(p), "tracker.threads = -2: must be in [0, 1024]");
  p = {};
  p.tolerance = std::nan("");
  EXPECT_EQ(message(p), "tracker.tolerance_m = nan: must be in [0, 1]");
  p = {};
  p.geometry.ball_radius = 0;
  EXPECT_EQ(message(p), "geometry.ball_radius_m = 0: must be in [0.0001, 1]");
  p = {};
  p.geometry.pitch = 0.01;
  EXPECT_EQ(message(p), "geometry.pitch_m = 0.01: must be > ball_radius_m (0.015)");
  // The error carries the key apart from the message, for readers to find its line.
  p = {};
  p.policy.lsq_init.poly_order = 12;
  try {
    p.validate();
    FAIL() << "no error";
  } catch (const fields::FieldError& e) {
    EXPECT_EQ(e.key(), "poly_order");
    EXPECT_EQ(e.value(), "12");
    EXPECT_EQ(e.rule(), "must be in [1, 9]");
  }
  EXPECT_EQ(parse_init("paper"), InitMethod::paper);
}

}  // namespace
}  // namespace linksight
