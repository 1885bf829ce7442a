// Every back end against the serial reference: same associations, sums within rounding,
// and the same result whatever the thread count.
#include <gtest/gtest.h>

#include "linksight/tracker/backend.hpp"
#include "linksight/tracker/tracker.hpp"
#include "test_support.hpp"

namespace linksight {
namespace {

using test::kBackendTolerance;

Cloud big_cloud(std::size_t target, std::uint64_t seed) {
  sim::SurfaceSampling s;
  s.noise_sigma = 0.002;
  s.seed = seed;
  s.samples_per_ball = static_cast<int>(target / 6);  // ~half of each ball faces the camera
  s.samples_per_neck = static_cast<int>(target / 40);
  return sim::sample_visible_surface(test::test_chain(sim::ChainShape::s_shape), {}, s);
}

class BackendEquivalence : public ::testing::TestWithParam<BackendKind> {};

TEST_P(BackendEquivalence, OneAssociationPassMatchesSerial) {
  const Cloud cloud = big_cloud(20000, 5);
  ASSERT_GT(cloud.size(), 15000u);
  const test::Soa pts(cloud);
  const Nodes truth = test::test_chain(sim::ChainShape::s_shape);
  std::vector<float> q;
  for (const auto& n : truth) {
    for (int a = 0; a < 3; ++a) q.push_back(static_cast<float>(n[a]));
  }
  auto serial = make_backend(BackendKind::serial, 0);
  auto other = make_backend(GetParam(), 2);
  std::vector<std::int32_t> a_ref(cloud.size()), a_other(cloud.size());
  Accumulation acc_ref, acc_other;
  serial->associate(pts.view(), q, a_ref.data(), acc_ref);
  other->associate(pts.view(), q, a_other.data(), acc_other);
  EXPECT_EQ(a_ref, a_other);
  EXPECT_EQ(acc_ref.count, acc_other.count);
  for (std::size_t j = 0; j < acc_ref.count.size(); ++j) {
    for (int a = 0; a < 3; ++a) {
      const double m_ref = acc_ref.sum[3 * j + a] / acc_ref.count[j];
      const double m_other = acc_other.sum[3 * j + a] / acc_other.count[j];
      EXPECT_NEAR(m_ref, m_other, kBackendTolerance);
    }
  }
  // Brute-force check of Eq. 11 on the reference, in the kernels' float arithmetic.
  for (std::size_t i = 0; i < cloud.size(); i += 97) {
    int best = 0;
    float best_d = std::numeric_limits<float>::infinity();
    for (int j = 0; j < static_cast<int>(truth.size()); ++j) {
      const float dx = pts.x[i] - q[3 * j], dy = pts.y[i] - q[3 * j + 1],
                  dz = pts.z[i] - q[3 * j + 2];
      const float d = dx * dx + dy * dy + dz * dz;
      if (d < best_d) {
        best_d = d;
        best = j;
      }
    }
    ASSERT_EQ(a_ref[i], best) << "point " << i;
  }
}

TEST_P(BackendEquivalence, TrackerSequenceMatchesSerialOn20kPoints) {
  TrackerParams p;
  p.backend = BackendKind::serial;
  Tracker ref(p);
  p.backend = GetParam();
  p.threads = 2;
  Tracker other(p);
  for (int f = 0; f < 5; ++f) {
    const Cloud cloud = big_cloud(20000, 100 + f);
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
    for (std::size_t j = 0; j < r.nodes.size(); ++j) {
      EXPECT_LT((r.nodes[j] - o.nodes[j]).norm(), kBackendTolerance)
          << "frame " << f << " node " << j;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Backends, BackendEquivalence,
                         ::testing::Values(BackendKind::serial, BackendKind::openmp),
                         test::backend_name);

TEST(OpenMPBackend, BitIdenticalForAnyThreadCount) {
  const Cloud cloud = big_cloud(50000, 9);
  const test::Soa pts(cloud);
  std::vector<float> q;
  for (const auto& n : test::test_chain(sim::ChainShape::c_shape)) {
    for (int a = 0; a < 3; ++a) q.push_back(static_cast<float>(n[a]));
  }
  Accumulation first;
  std::vector<std::int32_t> first_assoc(cloud.size());
  make_backend(BackendKind::openmp, 1)->associate(pts.view(), q, first_assoc.data(), first);
  for (int threads : {2, 3, 5}) {
    Accumulation acc;
    std::vector<std::int32_t> assoc(cloud.size(), -1);
    make_backend(BackendKind::openmp, threads)->associate(pts.view(), q, assoc.data(), acc);
    EXPECT_EQ(assoc, first_assoc) << threads << " threads";
    EXPECT_EQ(acc.sum, first.sum) << threads << " threads";  // exact, not approximate
    EXPECT_EQ(acc.count, first.count);
  }
}

TEST(Backend, ParseNamesTheBadValue) {
  EXPECT_EQ(parse_backend("openmp"), BackendKind::openmp);
  try {
    (void)parse_backend("cuda");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'cuda'"), std::string::npos);
  }
  EXPECT_THROW((void)make_backend(BackendKind::openmp, -1), std::invalid_argument);
}

}  // namespace
}  // namespace linksight
