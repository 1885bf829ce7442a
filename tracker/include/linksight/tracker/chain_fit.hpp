#pragma once
/// @file Centres from a model fit, not from a mean (issue 17, part 2): the chain state
/// (chain_state.hpp) fitted to the points by robust Gauss–Newton on the distance from each
/// point to the component surfaces (ball of known radius ∪ neck capsule, the same shape as
/// the SDF metric, ComponentGeometry::sdf).

#include <cstddef>

#include "linksight/tracker/chain_state.hpp"
#include "linksight/tracker/fields.hpp"
#include "linksight/tracker/geometry.hpp"
#include "linksight/tracker/init.hpp"

namespace linksight {

struct ChainFitParams {
  int max_iterations = 20;
  /// Huber loss: residuals beyond this weigh linearly, not quadratically (flying pixels,
  /// rim pixels, stray points) [m].
  double huber = 0.001;
  /// A point farther than this from every component surface is not the link's [m].
  double max_distance = 0.01;
  /// Stop when no centre moves more than this in an iteration [m].
  double tolerance = 1e-8;
  /// The largest bend between neighbouring components [rad] (the chain's cone limit).
  double cone_limit = 25.0 * 3.14159265358979323846 / 180.0;

  template <class Archive>
  void fields(Archive& ar) {
    ar("max_iterations", max_iterations, fields::in(1, 1000));
    ar("huber_m", huber, fields::in(1e-6, 0.1));
    ar("max_distance_m", max_distance, fields::in(1e-4, 1));
    ar("tolerance_m", tolerance, fields::in(0, 1e-3));
    ar("cone_limit_deg", cone_limit, fields::deg(fields::in(0.1, 89.9)));
  }
  void validate() const { fields::check(*this, "chain_fit"); }
};

struct ChainFitResult {
  int iterations = 0;
  std::size_t inliers = 0;  ///< points within max_distance of the fitted chain's surface
  double rms = 0.0;         ///< RMS distance of the inliers to the surface [m]
};

/// The component a point lies nearest to (by the component SDF) and its signed distance
/// to that component's surface [m]; the component is -1 when the chain has none.
struct SurfaceHit {
  int component = -1;
  double distance = 0.0;
};
[[nodiscard]] SurfaceHit nearest_surface(const Eigen::Vector3d& p, const ChainState& chain,
                                         const ComponentGeometry& geometry);

/// Fits `chain` (the start, updated in place) to `points` [m, C]: each iteration
/// associates every point with its nearest component surface, then takes one damped
/// Gauss–Newton step in ball 0's centre and the axes' tangent rotations with Huber
/// weights, renormalizes the axes and bends joints back within the cone limit. The pitch
/// holds exactly throughout. Serial and deterministic (points summed in order).
ChainFitResult fit_chain(const PointsView& points, ChainState& chain,
                         const ComponentGeometry& geometry, const ChainFitParams& params);

}  // namespace linksight
