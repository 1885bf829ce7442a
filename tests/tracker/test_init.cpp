#include <gtest/gtest.h>

#include "linksight/tracker/init.hpp"
#include "test_support.hpp"

namespace linksight {
namespace {

using sim::ChainShape;
using test::Soa;

// Node j is in the right place in the order if the true centre nearest to it is j.
int order_errors(const Nodes& est, const Nodes& truth, int balls) {
  int errors = 0;
  for (int j = 0; j < balls; ++j) {
    int best = 0;
    for (int k = 1; k < balls; ++k) {
      if ((est[j] - truth[k]).norm() < (est[j] - truth[best]).norm()) best = k;
    }
    errors += best != j;
  }
  return errors;
}

int nearest_ball(const Eigen::Vector3d& q, const Nodes& truth, int balls) {
  int best = 0;
  for (int k = 1; k < balls; ++k) {
    if ((q - truth[k]).norm() < (q - truth[best]).norm()) best = k;
  }
  return best;
}

bool monotonic(const Nodes& est, const Nodes& truth, int balls) {
  for (std::size_t j = 1; j < est.size(); ++j) {
    if (nearest_ball(est[j], truth, balls) < nearest_ball(est[j - 1], truth, balls)) return false;
  }
  return true;
}

Cloud spheres_only(const Nodes& truth, std::uint64_t seed = 3) {
  sim::SurfaceSampling s;
  s.necks = false;
  s.seed = seed;
  return sim::sample_visible_surface(truth, ComponentGeometry{}, s);
}

TEST(Polynomial, FitRecoversAnExactCubic) {
  std::vector<double> u, v;
  for (int i = 0; i < 50; ++i) {
    const double x = -0.3 + 0.013 * i;
    u.push_back(x);
    v.push_back(0.2 - 1.5 * x + 0.7 * x * x + 3.0 * x * x * x);
  }
  const Polynomial p = fit_polynomial(u, v, 3);
  for (double x : {-0.25, 0.0, 0.1, 0.33}) {
    EXPECT_NEAR(p(x), 0.2 - 1.5 * x + 0.7 * x * x + 3.0 * x * x * x, 1e-10);
  }
}

TEST(Polynomial, ConstantAbscissaFitsTheMean) {
  const std::vector<double> u = {1.0, 1.0, 1.0}, v = {1.0, 2.0, 6.0};
  EXPECT_NEAR(fit_polynomial(u, v, 3)(1.0), 3.0, 1e-12);
}

class InitShapes : public ::testing::TestWithParam<ChainShape> {};

TEST_P(InitShapes, PcaOrdersNodesAlongTheLink) {
  const Nodes truth = test::test_chain(GetParam());
  const Soa pts(spheres_only(truth));
  InitParams p;
  p.method = InitMethod::pca;
  const Nodes nodes = lsq_init(pts.view(), 11, p);
  ASSERT_EQ(nodes.size(), 11u);
  EXPECT_EQ(order_errors(nodes, truth, 11), 0);
  // Sampled at the known pitch.
  for (std::size_t j = 0; j + 1 < nodes.size(); ++j) {
    EXPECT_NEAR((nodes[j + 1] - nodes[j]).norm(), p.pitch, 0.003);
  }
}

// The paper's form samples at constant x: on a bent link its nodes are not one per ball,
// but they run from one end to the other in order (what the SOM needs).
TEST_P(InitShapes, PaperInitIsMonotonicForALinkSeenBroadside) {
  const Nodes truth = test::test_chain(GetParam(), 0.1);
  const Soa pts(spheres_only(truth));
  InitParams p;
  p.method = InitMethod::paper;
  const Nodes nodes = lsq_init(pts.view(), 11, p);
  EXPECT_TRUE(monotonic(nodes, truth, 11));
  EXPECT_LE(nearest_ball(nodes.front(), truth, 11), 1);
  EXPECT_GE(nearest_ball(nodes.back(), truth, 11), 9);
}

std::string shape_name(const ::testing::TestParamInfo<ChainShape>& p) {
  static const char* const kNames[] = {"straight", "C", "S"};
  return kNames[static_cast<int>(p.param)];
}

INSTANTIATE_TEST_SUITE_P(Shapes, InitShapes,
                         ::testing::Values(ChainShape::straight, ChainShape::c_shape,
                                           ChainShape::s_shape),
                         shape_name);

// Eq. 9 samples over the marginal x range. A link hanging along the camera y axis has
// almost no x range, so y = a(x) is no function and the nodes come out of order; the
// principal-axis form is rotation invariant. (Tracking consequences: test_tracker.cpp.)
TEST(Init, PaperFormFailsForALinkAlongCameraYAndPcaDoesNot) {
  const Nodes truth = test::hanging_chain();
  const Soa pts(spheres_only(truth));
  InitParams p;
  p.method = InitMethod::paper;
  const Nodes paper = lsq_init(pts.view(), 11, p);
  p.method = InitMethod::pca;
  const Nodes pca = lsq_init(pts.view(), 11, p);
  EXPECT_EQ(order_errors(pca, truth, 11), 0);
  EXPECT_GT((pca.back() - pca.front()).norm(), 0.40);
  EXPECT_GE(order_errors(paper, truth, 11), 5);
}

TEST(Init, OrientationFollowsPreviousNodes) {
  const Nodes truth = test::test_chain(ChainShape::c_shape);
  const Soa pts(spheres_only(truth));
  InitParams p;
  const Nodes fresh = lsq_init(pts.view(), 11, p);
  Nodes reversed(truth.rbegin() + 1, truth.rend());  // 11 ball centres, tip end first
  const Nodes follow = lsq_init(pts.view(), 11, p, &reversed);
  EXPECT_TRUE(follow.front().isApprox(fresh.back(), 1e-12));
  EXPECT_TRUE(follow.back().isApprox(fresh.front(), 1e-12));
}

TEST(Init, ThinningIsDeterministicAndCloseToTheFullFit) {
  const Nodes truth = test::test_chain(ChainShape::s_shape);
  const Soa pts(spheres_only(truth));
  InitParams all;
  all.max_points = 0;
  InitParams thin;
  thin.max_points = 500;
  const Nodes a = lsq_init(pts.view(), 11, all);
  const Nodes b1 = lsq_init(pts.view(), 11, thin);
  const Nodes b2 = lsq_init(pts.view(), 11, thin);
  for (std::size_t j = 0; j < a.size(); ++j) {
    EXPECT_EQ(b1[j], b2[j]);
    EXPECT_LT((a[j] - b1[j]).norm(), 0.005);
  }
}

TEST(Init, SomStraightLineSpansTheCloud) {
  const Nodes truth = test::test_chain(ChainShape::straight);
  const Soa pts(spheres_only(truth));
  const Nodes n = som_init(pts.view(), 11, SomInit::straight_line, 0);
  EXPECT_EQ(order_errors(n, truth, 11), 0);
  EXPECT_NEAR((n.back() - n.front()).norm(), 10 * 0.045 + 2 * 0.015, 0.01);
}

TEST(Init, SomRandomSampleIsSeededAndDrawnFromTheCloud) {
  const Nodes truth = test::test_chain(ChainShape::c_shape);
  const Soa pts(spheres_only(truth));
  const Nodes a = som_init(pts.view(), 11, SomInit::random_sample, 42);
  const Nodes b = som_init(pts.view(), 11, SomInit::random_sample, 42);
  const Nodes c = som_init(pts.view(), 11, SomInit::random_sample, 43);
  EXPECT_EQ(a, b);
  EXPECT_NE(a, c);
  for (const auto& q : a) {
    bool found = false;
    for (std::size_t i = 0; i < pts.x.size() && !found; ++i) {
      found = q == Eigen::Vector3d(pts.x[i], pts.y[i], pts.z[i]);
    }
    EXPECT_TRUE(found);
  }
}

TEST(Init, ValidateNamesTheField) {
  InitParams p;
  p.poly_order = 0;
  try {
    p.validate();
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("lsq_init.poly_order = 0: must be in [1, 9]"), std::string::npos);
  }
}

TEST(SomInit, NamesRoundTripAndBadOnesAreNamed) {
  for (const SomInit m : {SomInit::straight_line, SomInit::random_sample})
    EXPECT_EQ(parse_som_init(to_string(m)), m);
  EXPECT_EQ(to_string(SomInit::random_sample), "random-sample");
  EXPECT_EQ(test::error_of<std::invalid_argument>([] { (void)parse_som_init("grid"); }),
            "unknown SOM init 'grid' (expected straight-line or random-sample)");
}

}  // namespace
}  // namespace linksight
