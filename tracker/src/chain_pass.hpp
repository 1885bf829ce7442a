#pragma once
// chain-fit's pass over the points (chain_fit.cpp), as the CPU computes it and as a device
// back end (OpenCL) reproduces it: the chain at one linearization point, what a pass
// sums, and the interface a back end implements to run passes itself.

#include <Eigen/Core>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "chain_search.hpp"
#include "linksight/tracker/chain_fit.hpp"

namespace linksight {
namespace detail {

// Points are summed in fixed blocks, each block in order and the blocks in order, so the
// sums are the same bits for any thread count (serial is one thread of the same code) and
// on a device that sums the same blocks the same way.
inline constexpr std::size_t kChainBlock = 2048;

// Component k's surface lies within this of its centre: the CPU's search skips a component
// whose centre is farther than the nearest centre's ball distance plus this (and a margin,
// chain_search.hpp).
inline double chain_search_reach(const ComponentGeometry& g) {
  return std::max(g.ball_radius, g.neck_length + g.neck_radius);
}

// Values per point that the device's first kernel writes (chain.cl's VALS, passed to its
// build): robust cost, residual, weight, then the 5 Jacobian entries.
inline constexpr int kChainValues = 8;

// The chain at one linearization point: centres, axes and each axis's tangent basis, and
// the components' centres and axes again as arrays for the per-point search.
struct ChainFrames {
  Nodes centre;                           // count + 1 (the last is the tip node)
  std::vector<Eigen::Vector3d> t1, t2;    // tangents of axis k, a rotation's directions
  std::vector<double> cx, cy, cz, ax, ay, az;  // count each
  ChainSearchFrames search;               // the same in float, for the search
};

// The search's float copies of f's centres and axes and of g's sizes: rounded to nearest,
// as the device converts its doubles.
inline ChainSearchFrames search_frames(const ChainFrames& f, const ComponentGeometry& g) {
  const auto to_f = [](const std::vector<double>& v) {
    return std::vector<float>(v.begin(), v.end());
  };
  ChainSearchFrames s;
  s.cx = to_f(f.cx);
  s.cy = to_f(f.cy);
  s.cz = to_f(f.cz);
  s.ax = to_f(f.ax);
  s.ay = to_f(f.ay);
  s.az = to_f(f.az);
  s.r = static_cast<float>(g.ball_radius);
  s.rn = static_cast<float>(g.neck_radius);
  s.L = static_cast<float>(g.neck_length);
  s.reach = static_cast<float>(chain_search_reach(g));
  return s;
}

// A point's residual depends on its own component only, through u = [dc_k; dtheta_k]: the
// move of ball k's centre and the tangent rotation of axis k (which moves a neck point by
// s along the tangent). So a pass sums, per component, the 5x5 normal equations in u; the
// chain rule to the chain's parameters is applied once per pass (assemble), not per point.
using Mat5 = Eigen::Matrix<double, 5, 5>;
using Vec5 = Eigen::Matrix<double, 5, 1>;

// What one block of points contributes: per component the normal equations in u, the
// inlier count, and the block's robust cost and inliers' sum of squared distances.
struct ChainSums {
  std::vector<Mat5> H;
  std::vector<Vec5> b;
  std::vector<std::int64_t> count;
  double robust = 0;
  double sum2 = 0;
  std::size_t inliers = 0;

  explicit ChainSums(std::size_t components)
      : H(components, Mat5::Zero()), b(components, Vec5::Zero()), count(components, 0) {}
  void add(const ChainSums& o) {
    for (std::size_t k = 0; k < H.size(); ++k) {
      H[k] += o.H[k];
      b[k] += o.b[k];
      count[k] += o.count[k];
    }
    robust += o.robust;
    sum2 += o.sum2;
    inliers += o.inliers;
  }
};

}  // namespace detail

/// Runs chain-fit's passes where a back end keeps the points (Backend::chain_pass_device):
/// the same per-point arithmetic in double, summed in the same blocks in the same order,
/// so the sums, and with them the fit, are the CPU's bits.
class ChainPassDevice {
 public:
  virtual ~ChainPassDevice() = default;
  /// The frame's points, once per frame before its passes.
  virtual void set_chain_points(const PointsView& points) = 0;
  /// One pass over every `stride`-th point of each block (kChainBlock) at `f`: with
  /// `search`, each point's nearest component, recorded in association buffer `write` (0
  /// or 1); else buffer `read`'s, reused.
  virtual detail::ChainSums chain_pass(const detail::ChainFrames& f, const ComponentGeometry& g,
                                       const ChainFitParams& params, bool search, int read,
                                       int write, std::size_t stride) = 0;
};

}  // namespace linksight
