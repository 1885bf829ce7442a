#pragma once
/// @file The link's shape as a state whose geometry always holds (issue 17, part 1): the
/// first ball's centre and one unit axis per component, so that every ball centre is
/// exactly one pitch from the next whatever values the state takes.

#include <Eigen/Core>
#include <vector>

#include "linksight/tracker/geometry.hpp"
#include "linksight/tracker/model.hpp"

namespace linksight {

/// A chain of `geometry.count` components in the camera frame C.
///
/// Component k's frame has its origin at ball centre c_k and its +Z along `axis[k]`
/// (paper Fig. 2); the next ball sits one pitch along it: c_{k+1} = c_k + pitch axis[k].
/// The last component's axis points at the tip node, one pitch beyond the last ball, as
/// the truth defines it. The bend of joint k (between components k-1 and k) is the angle
/// between axis[k-1] and axis[k].
struct ChainState {
  Eigen::Vector3d c0 = Eigen::Vector3d::Zero();  ///< ball 0's centre [m, C]
  std::vector<Eigen::Vector3d> axis;             ///< count unit vectors, component k's +Z

  /// The M+1 = count+1 reference points: the ball centres, then the tip node [m, C].
  [[nodiscard]] Nodes nodes(double pitch) const;
  /// Ball k's centre [m, C], k in [0, count]; k = count is the tip node.
  [[nodiscard]] Eigen::Vector3d centre(int k, double pitch) const;
  /// The largest bend over the joints between components [rad].
  [[nodiscard]] double max_bend() const;
};

/// The chain nearest `nodes` (count+1 points): c0 = nodes[0], axis[k] the direction
/// from nodes[k] to nodes[k+1] (the previous axis, or +Z for the first, where two
/// nodes coincide). Lengths between the nodes are discarded: the result has the
/// geometry's pitch exactly. Throws std::invalid_argument when nodes.size() is not
/// geometry.count + 1 or a node is not finite.
[[nodiscard]] ChainState chain_from_nodes(const Nodes& nodes, const ComponentGeometry& geometry);

/// Bends every joint back within `cone_limit` [rad], from the base outwards: an axis
/// that bends more than the limit from its predecessor is turned toward it, in the plane
/// they span, until it bends exactly the limit (an axis opposite its predecessor turns in
/// the plane of the predecessor and the next axis, or any plane). Axes within the limit
/// are left bit for bit. Returns how many joints were bent back.
int limit_bends(ChainState& chain, double cone_limit);

}  // namespace linksight
