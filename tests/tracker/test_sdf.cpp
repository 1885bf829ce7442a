#include <gtest/gtest.h>

#include "linksight/tracker/sdf.hpp"
#include "test_support.hpp"

namespace linksight {
namespace {

TEST(SdfError, ZeroForNoiseFreeBareBallsAtTheTrueNodes) {
  ComponentGeometry bare;  // a zero-length neck hides inside the ball
  bare.neck_length = 0.0;
  const Nodes truth = test::test_chain(sim::ChainShape::c_shape, 0.15, bare);
  sim::SurfaceSampling s;
  s.necks = false;
  const test::Soa pts(sim::sample_visible_surface(truth, bare, s));
  // Float storage of the points leaves ~1e-8 m.
  EXPECT_LT(sdf_error(pts.view(), truth, bare), 1e-6);
}

// Eq. 13 associates each point with its nearest node, so the neck points of component j
// that lie nearer ball j+1 are measured in frame j+1, whose shape has no backward neck.
// That leaves a floor on perfect data with necks: measured 0.25 mm here.
TEST(SdfError, NearestNodeAssociationLeavesAFloorWithNecks) {
  const Nodes truth = test::test_chain(sim::ChainShape::c_shape);
  const test::Soa pts(sim::sample_visible_surface(truth, {}, {}));
  const double e = sdf_error(pts.view(), truth, {});
  EXPECT_GT(e, 0.0001);
  EXPECT_LT(e, 0.0005);
}

TEST(SdfError, EqualsARadialOffsetOfTheBallSurface) {
  const Nodes truth = test::test_chain(sim::ChainShape::straight);
  const ComponentGeometry g;
  sim::SurfaceSampling s;
  s.necks = false;
  const Cloud surface = sim::sample_visible_surface(truth, g, s);
  // Push every ball point 2 mm outward along its normal: mean |SDF| = 2 mm (Eq. 16).
  Cloud pushed;
  for (std::size_t i = 0; i < surface.size(); ++i) {
    const Eigen::Vector3d p = surface.point(i);
    std::size_t k = 0;
    for (std::size_t j = 1; j + 1 < truth.size(); ++j) {
      if ((p - truth[j]).norm() < (p - truth[k]).norm()) k = j;
    }
    pushed.push_back(Eigen::Vector3d(p + 0.002 * (p - truth[k]).normalized()));
  }
  const test::Soa pts(pushed);
  EXPECT_NEAR(sdf_error(pts.view(), truth, g), 0.002, 2e-5);
}

TEST(SdfError, GrowsWhenTheNodesAreWrong) {
  const Nodes truth = test::test_chain(sim::ChainShape::s_shape);
  const test::Soa pts(sim::sample_visible_surface(truth, {}, {}));
  Nodes shifted = truth;
  for (auto& n : shifted) n += Eigen::Vector3d(0, 0.005, 0);
  const double e = sdf_error(pts.view(), shifted, {});
  EXPECT_GT(e, 0.002);
  EXPECT_LT(e, 0.006);
}

TEST(SdfError, NanWithoutPoints) {
  const test::Soa pts(Cloud{});
  EXPECT_TRUE(std::isnan(sdf_error(pts.view(), test::test_chain(sim::ChainShape::straight), {})));
}

}  // namespace
}  // namespace linksight
