// chain_search.hpp: chain-fit's float search, two vectors of points at a time, skipping
// components that cannot win, against the definition the device computes (every component's
// float distance, the argmin, ties to the lower index).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include "chain_pass.hpp"
#include "chain_search.hpp"
#include "linksight/tracker/chain_fit.hpp"
#include "test_support.hpp"

namespace linksight {
namespace {

using detail::ChainSearchFrames;

// The definition, one point at a time in scalar float: chain.cl's distance_f and its loop.
std::int16_t brute_force(float px, float py, float pz, const ChainSearchFrames& f) {
  float best = std::numeric_limits<float>::infinity();
  std::int16_t bk = 0;
  for (std::size_t k = 0; k < f.cx.size(); ++k) {
    const float dx = px - f.cx[k], dy = py - f.cy[k], dz = pz - f.cz[k];
    const float ball = std::sqrt(dx * dx + dy * dy + dz * dz) - f.r;
    const float t = dx * f.ax[k] + dy * f.ay[k] + dz * f.az[k];
    const float lo = t < 0.0f ? 0.0f : t;
    const float s = f.L < lo ? f.L : lo;
    const float ex = dx - s * f.ax[k], ey = dy - s * f.ay[k], ez = dz - s * f.az[k];
    const float neck = std::sqrt(ex * ex + ey * ey + ez * ez) - f.rn;
    const float d = neck < ball ? neck : ball;
    if (d < best) {
      best = d;
      bk = static_cast<std::int16_t>(k);
    }
  }
  return bk;
}

// The test link's components in float, through the rounding chain_fit.cpp uses.
ChainSearchFrames frames_of(const Nodes& nodes, const ComponentGeometry& g) {
  detail::ChainFrames f;
  std::vector<double>* const centre[3] = {&f.cx, &f.cy, &f.cz};
  std::vector<double>* const axis[3] = {&f.ax, &f.ay, &f.az};
  for (std::size_t k = 0; k + 1 < nodes.size(); ++k) {
    const Eigen::Vector3d a = (nodes[k + 1] - nodes[k]).normalized();
    for (int i = 0; i < 3; ++i) {
      centre[i]->push_back(nodes[k][i]);
      axis[i]->push_back(a[i]);
    }
  }
  return detail::search_frames(f, g);
}

struct Points {
  std::vector<float> x, y, z;
  void add(const Eigen::Vector3d& p) {
    x.push_back(static_cast<float>(p.x()));
    y.push_back(static_cast<float>(p.y()));
    z.push_back(static_cast<float>(p.z()));
  }
};

// Points on and around every component of the bent test link (surface noise of 0-20 mm,
// inside the balls, on the necks' axes), far away up to 100 m (kMaxCoordinate), and on the
// planes halfway between neighbouring centres, where two components tie or nearly so.
Points points_around(const Nodes& nodes, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n(0.0, 1.0);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Points p;
  for (int i = 0; i < 4000; ++i) {
    const auto k = static_cast<std::size_t>(u(rng) * static_cast<double>(nodes.size() - 1));
    const Eigen::Vector3d c = nodes[k] + u(rng) * (nodes[k + 1] - nodes[k]);
    const Eigen::Vector3d dir = Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized();
    p.add(c + (0.02 * u(rng)) * dir);
  }
  for (std::size_t k = 0; k + 1 < nodes.size(); ++k) {
    p.add(nodes[k]);                         // a centre
    p.add(0.5 * (nodes[k] + nodes[k + 1]));  // halfway: on the neck's axis
    const Eigen::Vector3d a = (nodes[k + 1] - nodes[k]).normalized();
    for (int j = 0; j < 8; ++j)  // the bisecting plane
      p.add(0.5 * (nodes[k] + nodes[k + 1]) + 0.01 * j * a.unitOrthogonal());
  }
  for (int i = 0; i < 64; ++i) {
    const Eigen::Vector3d dir = Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized();
    p.add(std::pow(10.0, -1.0 + 3.0 * u(rng)) * dir);  // 0.1 m to 100 m from the camera
  }
  return p;
}

TEST(ChainSearch, SkippingComponentsGivesTheBruteForceAnswer) {
  const ComponentGeometry g;
  for (const sim::ChainShape shape :
       {sim::ChainShape::straight, sim::ChainShape::c_shape, sim::ChainShape::s_shape}) {
    // Bent hard (0.6 rad a joint) so that far components come near each other too.
    for (const double bend : {0.15, 0.6}) {
      const Nodes nodes = test::test_chain(shape, bend);
      const ChainSearchFrames f = frames_of(nodes, g);
      const Points p = points_around(nodes, 7);
      // Both widths (SSE's 4 lanes, AVX2's 8) and the dispatching entry point.
      for (const int lanes : {0, 4, 8}) {
        std::vector<std::int16_t> got(p.x.size(), -1);
        if (lanes == 0)
          detail::chain_search_range(p.x.data(), p.y.data(), p.z.data(), 0, p.x.size(), 1, f,
                                     got.data());
        else
          detail::chain_search_range_lanes(lanes, p.x.data(), p.y.data(), p.z.data(), 0, p.x.size(),
                                           1, f, got.data());
        int mismatches = 0, winners_seen = 0;
        std::vector<bool> seen(f.cx.size(), false);
        for (std::size_t i = 0; i < p.x.size(); ++i) {
          const std::int16_t want = brute_force(p.x[i], p.y[i], p.z[i], f);
          mismatches += got[i] != want;
          if (!seen[static_cast<std::size_t>(want)]) ++winners_seen;
          seen[static_cast<std::size_t>(want)] = true;
        }
        EXPECT_EQ(mismatches, 0) << "bend " << bend << ", lanes " << lanes;
        EXPECT_EQ(winners_seen, static_cast<int>(f.cx.size())) << "every component wins somewhere";
      }
    }
  }
}

TEST(ChainSearch, StridesAndTailsTakeTheSameAnswers) {
  const ComponentGeometry g;
  const Nodes nodes = test::test_chain(sim::ChainShape::s_shape);
  const ChainSearchFrames f = frames_of(nodes, g);
  const Points p = points_around(nodes, 11);
  for (const std::size_t stride : {std::size_t{1}, std::size_t{3}, std::size_t{8}}) {
    for (const std::size_t begin : {std::size_t{0}, std::size_t{5}}) {
      const std::size_t end = p.x.size() - 3;  // not a multiple of 8: a padded tail
      for (const int lanes : {4, 8}) {
        std::vector<std::int16_t> got(p.x.size(), -7);
        detail::chain_search_range_lanes(lanes, p.x.data(), p.y.data(), p.z.data(), begin, end,
                                         stride, f, got.data());
        for (std::size_t i = 0; i < p.x.size(); ++i) {
          const bool taken = i >= begin && i < end && (i - begin) % stride == 0;
          if (taken) {
            ASSERT_EQ(got[i], brute_force(p.x[i], p.y[i], p.z[i], f))
                << "stride " << stride << ", lanes " << lanes << ", point " << i;
          } else {
            ASSERT_EQ(got[i], -7) << "stride " << stride << ": point " << i << " was written";
          }
        }
      }
    }
  }
}

// Ties go to the lower index: two components with the same centre and axis.
TEST(ChainSearch, TiesGoToTheLowerIndex) {
  const ComponentGeometry g;
  Nodes nodes = test::test_chain(sim::ChainShape::straight);
  ChainSearchFrames f = frames_of(nodes, g);
  for (std::vector<float>* v : {&f.cx, &f.cy, &f.cz, &f.ax, &f.ay, &f.az}) (*v)[6] = (*v)[4];
  Points p;
  for (int j = 0; j < 9; ++j) p.add(nodes[4] + Eigen::Vector3d(0.001 * j, 0.02, 0.0));
  std::vector<std::int16_t> got(p.x.size(), -1);
  detail::chain_search_range(p.x.data(), p.y.data(), p.z.data(), 0, p.x.size(), 1, f, got.data());
  for (std::size_t i = 0; i < got.size(); ++i) EXPECT_EQ(got[i], 4) << "point " << i;
}

// Through the public API: nearest_surface's component is the nearest one in double up to
// the float search's rounding, and its distance is that component's, in double.
TEST(ChainSearch, NearestSurfaceIsTheNearestComponentUpToFloatRounding) {
  const ComponentGeometry g;
  const Nodes nodes = test::test_chain(sim::ChainShape::c_shape, 0.6);
  const ChainState chain = chain_from_nodes(nodes, g);
  const Points p = points_around(nodes, 13);
  constexpr double kFloatRounding = 1e-6;  // [m]: a few ulp of a 100 m float coordinate
  for (std::size_t i = 0; i < p.x.size(); ++i) {
    const Eigen::Vector3d q(p.x[i], p.y[i], p.z[i]);
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k + 1 < nodes.size(); ++k) {
      // Component k in its own frame K: centre at the origin, neck along +Z.
      const Eigen::Vector3d a = (nodes[k + 1] - nodes[k]).normalized();
      const Eigen::Quaterniond R = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), a);
      best = std::min(best, g.sdf(R.conjugate() * (q - nodes[k])));
    }
    const SurfaceHit h = nearest_surface(q, chain, g);
    ASSERT_GE(h.component, 0);
    EXPECT_NEAR(h.distance, best, kFloatRounding * std::max(1.0, q.norm())) << "point " << i;
  }
}

}  // namespace
}  // namespace linksight
