#pragma once
/// @file SDF error metric (Section VI, Eqs. 13–16).

#include "linksight/tracker/geometry.hpp"
#include "linksight/tracker/init.hpp"
#include "linksight/tracker/model.hpp"

namespace linksight {

/// Mean |SDF| [m] of the points against the link described by `nodes` (Eq. 16).
/// Each point is associated with its nearest node (Eq. 13), moved into that node's
/// component frame (Eq. 14; the last node, a point on frame M-1's axis, uses frame
/// M-1) and evaluated against `geometry` (Eq. 15). Returns NaN for no points.
[[nodiscard]] double sdf_error(const PointsView& points, const Nodes& nodes,
                               const ComponentGeometry& geometry);

}  // namespace linksight
