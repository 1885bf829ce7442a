#pragma once
// The benches' cloud: one geometry at every size, so sizes compare.

#include <Eigen/Geometry>

#include "linksight/sim/synthetic_chain.hpp"
#include "linksight/tracker/cloud.hpp"

namespace linksight::bench {

// Exactly n points spread over the whole S-shaped test link with 1 mm noise (an even
// stride through a denser sample), so every size measures the same geometry.
inline Cloud make_cloud(std::size_t n) {
  Eigen::Isometry3d X_CB = Eigen::Isometry3d::Identity();
  X_CB.translation() = Eigen::Vector3d(-0.22, -0.02, 0.6);
  const ComponentGeometry g;
  const Nodes truth =
      sim::chain_nodes(g, sim::shape_bends(sim::ChainShape::s_shape, g.count, 0.1), X_CB);
  sim::SurfaceSampling s;
  s.samples_per_ball = static_cast<int>(n / 3 + 100);
  s.samples_per_neck = static_cast<int>(n / 20 + 20);
  s.noise_sigma = 0.001;
  const Cloud raw = sim::sample_visible_surface(truth, g, s);
  Cloud out;
  out.reserve(n);
  for (std::size_t i = 0; i < n; ++i) out.push_back(raw.point(i * raw.size() / n));
  return out;
}

}  // namespace linksight::bench
