// Every back end against the serial reference: same associations, sums within rounding,
// and the same result whatever the thread count or work-group size.
#include <gtest/gtest.h>

#include <numeric>

#include "linksight/tracker/backend.hpp"
#include "linksight/tracker/tracker.hpp"
#include "test_support.hpp"

namespace linksight {
namespace {

using test::BackendCase;

Cloud big_cloud(std::size_t target, std::uint64_t seed) {
  sim::SurfaceSampling s;
  s.noise_sigma = 0.002;
  s.seed = seed;
  s.samples_per_ball = static_cast<int>(target / 6);  // ~half of each ball faces the camera
  s.samples_per_neck = static_cast<int>(target / 40);
  return sim::sample_visible_surface(test::test_chain(sim::ChainShape::s_shape), {}, s);
}

std::vector<float> as_float(const Nodes& nodes) {
  std::vector<float> q;
  for (const auto& n : nodes) {
    for (int a = 0; a < 3; ++a) q.push_back(static_cast<float>(n[a]));
  }
  return q;
}

struct Pass {
  std::vector<std::int32_t> assoc;
  Accumulation acc;
};
Pass one_pass(Backend& b, const PointsView& v, const std::vector<float>& q) {
  Pass p;
  b.set_points(v);
  b.associate(q, p.acc);
  const auto a = b.association();
  p.assoc.assign(a.begin(), a.end());
  return p;
}

// Fixed-point sums make every back end bit-identical to serial, not just close.
void expect_same_as(const Pass& ref, const Pass& other) {
  EXPECT_EQ(ref.assoc, other.assoc);
  EXPECT_EQ(ref.acc.count, other.acc.count);
  EXPECT_EQ(ref.acc.sum, other.acc.sum);
}

class BackendEquivalence : public ::testing::TestWithParam<BackendCase> {
 protected:
  void SetUp() override { LINKSIGHT_SKIP_IF_UNBUILT(GetParam()); }
};

TEST_P(BackendEquivalence, OneAssociationPassMatchesSerial) {
  const Cloud cloud = big_cloud(20000, 5);
  ASSERT_GT(cloud.size(), 15000u);
  const test::Soa pts(cloud);
  const std::vector<float> q = as_float(test::test_chain(sim::ChainShape::s_shape));
  auto serial = make_backend(BackendKind::serial, 0);
  auto other = test::make(GetParam());
  const Pass ref = one_pass(*serial, pts.view(), q);
  expect_same_as(ref, one_pass(*other, pts.view(), q));
  // Brute-force check of Eq. 11 on the reference, in the kernels' float arithmetic.
  const int m = static_cast<int>(q.size() / 3);
  for (std::size_t i = 0; i < cloud.size(); i += 97) {
    int best = 0;
    float best_d = std::numeric_limits<float>::infinity();
    for (int j = 0; j < m; ++j) {
      const float dx = pts.x[i] - q[3 * j], dy = pts.y[i] - q[3 * j + 1],
                  dz = pts.z[i] - q[3 * j + 2];
      const float d = dx * dx + dy * dy + dz * dz;
      if (d < best_d) {
        best_d = d;
        best = j;
      }
    }
    ASSERT_EQ(ref.assoc[i], best) << "point " << i;
  }
}

// 0, 1 and 11 points (fewer than nodes), and 1,000,000 points.
TEST_P(BackendEquivalence, TinyAndHugeClouds) {
  const std::vector<float> q = as_float(test::test_chain(sim::ChainShape::c_shape));
  auto serial = make_backend(BackendKind::serial, 0);
  auto other = test::make(GetParam());
  const Cloud big = big_cloud(1200000, 8);
  for (std::size_t n : {std::size_t{0}, std::size_t{1}, std::size_t{11}, std::size_t{1000000}}) {
    ASSERT_GE(big.size(), n);
    Cloud c;
    for (std::size_t i = 0; i < n; ++i)
      c.push_back(big.point(i * (big.size() / std::max<std::size_t>(n, 1))));
    const test::Soa pts(c);
    const Pass ref = one_pass(*serial, pts.view(), q);
    const Pass o = one_pass(*other, pts.view(), q);
    SCOPED_TRACE(n);
    expect_same_as(ref, o);
    EXPECT_EQ(std::accumulate(o.acc.count.begin(), o.acc.count.end(), std::int64_t{0}),
              static_cast<std::int64_t>(n));
  }
}

TEST_P(BackendEquivalence, TrackerSequenceMatchesSerialOn20kPoints) {
  TrackerParams p = test::paper_params();
  Tracker ref(p);
  Tracker other(test::params_for(GetParam()));
  for (int f = 0; f < 5; ++f) {
    // Grows, shrinks and grows again: buffers must follow.
    const Cloud cloud = big_cloud(f == 2 ? 8000 : 20000 + 3000 * f, 100 + f);
    const FrameResult r = ref.step(cloud);
    const FrameResult o = other.step(cloud);
    ASSERT_EQ(r.nodes.size(), o.nodes.size());
    EXPECT_EQ(r.counts, o.counts);
    EXPECT_EQ(r.reinit, o.reinit);
    EXPECT_EQ(r.iterations, o.iterations);
    const auto ar = ref.last_association();
    const auto ao = other.last_association();
    ASSERT_EQ(ar.size(), ao.size());
    EXPECT_TRUE(std::equal(ar.begin(), ar.end(), ao.begin()));
    EXPECT_EQ(r.nodes, o.nodes) << "frame " << f;  // bit-identical, so within 1e-6 m
  }
}

// Every tracker test cloud (straight, C, S, noisy, emptied neighbourhoods), 12 frames:
// bit-identical nodes and associations in every frame, so nothing drifts over a run.
TEST_P(BackendEquivalence, BitIdenticalTrackingOnEveryTestCloud) {
  for (sim::ChainShape shape :
       {sim::ChainShape::straight, sim::ChainShape::c_shape, sim::ChainShape::s_shape}) {
    Tracker ref(test::paper_params());
    Tracker other(test::params_for(GetParam()));
    const Nodes truth = test::test_chain(shape);
    for (int f = 0; f < 12; ++f) {
      sim::SurfaceSampling s;
      s.noise_sigma = f < 4 ? 0.0 : 0.003;
      s.seed = 300 + f;
      if (f >= 6 && f < 9) s.hidden = {4, 5};  // emptied neighbourhoods: re-initialization
      const Cloud cloud = sim::sample_visible_surface(truth, {}, s);
      const FrameResult r = ref.step(cloud), o = other.step(cloud);
      SCOPED_TRACE("shape " + std::to_string(static_cast<int>(shape)) + " frame " +
                   std::to_string(f));
      EXPECT_EQ(r.reinit, o.reinit);
      EXPECT_EQ(r.nodes, o.nodes);  // exact
      EXPECT_EQ(r.counts, o.counts);
      const auto ar = ref.last_association(), ao = other.last_association();
      ASSERT_EQ(ar.size(), ao.size());
      EXPECT_TRUE(std::equal(ar.begin(), ar.end(), ao.begin()));
      if (f >= 6 && f < 9) {
        EXPECT_TRUE(o.reinit);
      }
    }
  }
}

// One back end, a different number of nodes from pass to pass.
TEST_P(BackendEquivalence, NodeCountMayChangeBetweenPasses) {
  const test::Soa pts(big_cloud(5000, 11));
  const Nodes truth = test::test_chain(sim::ChainShape::c_shape);
  auto serial = make_backend(BackendKind::serial, 0);
  auto other = test::make(GetParam());
  for (std::size_t m : {12u, 3u, 1u, 7u}) {
    const std::vector<float> q =
        as_float(Nodes(truth.begin(), truth.begin() + static_cast<long>(m)));
    SCOPED_TRACE(m);
    expect_same_as(one_pass(*serial, pts.view(), q), one_pass(*other, pts.view(), q));
  }
}

// Serial against itself could not fail: only the other back ends are compared.
INSTANTIATE_TEST_SUITE_P(Backends, BackendEquivalence, ::testing::ValuesIn(test::other_backends()),
                         test::backend_name);

TEST(OpenMPBackend, BitIdenticalForAnyThreadCount) {
  const Cloud cloud = big_cloud(50000, 9);
  const test::Soa pts(cloud);
  const std::vector<float> q = as_float(test::test_chain(sim::ChainShape::c_shape));
  const Pass first = one_pass(*make_backend(BackendKind::openmp, 1), pts.view(), q);
  for (int threads : {2, 3, 5}) {
    const Pass p = one_pass(*make_backend(BackendKind::openmp, threads), pts.view(), q);
    EXPECT_EQ(p.assoc, first.assoc) << threads << " threads";
    EXPECT_EQ(p.acc.sum, first.acc.sum) << threads << " threads";  // exact, not approximate
    EXPECT_EQ(p.acc.count, first.acc.count);
  }
}

TEST(Backend, ParseNamesTheBadValue) {
  EXPECT_EQ(parse_backend("openmp"), BackendKind::openmp);
  EXPECT_EQ(parse_backend("opencl"), BackendKind::opencl);
  try {
    (void)parse_backend("cuda");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'cuda'"), std::string::npos);
  }
  EXPECT_THROW((void)make_backend(BackendKind::openmp, -1), std::invalid_argument);
  for (const ClAccumulation a : {ClAccumulation::reduction, ClAccumulation::atomic})
    EXPECT_EQ(parse_cl_accumulation(to_string(a)), a);
  EXPECT_EQ(test::error_of<std::invalid_argument>([] { (void)parse_cl_accumulation("fast"); }),
            "unknown accumulation 'fast' (expected reduction or atomic)");
}

}  // namespace
}  // namespace linksight
