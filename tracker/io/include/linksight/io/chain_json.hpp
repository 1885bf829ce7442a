#pragma once
/// @file The component geometry as JSON under a scene's `chain` keys (ComponentGeometry's
/// one field list): what a recording's chain.json holds and an external tracker's first
/// frame says about the link.

#include <string>

#include "linksight/tracker/geometry.hpp"

namespace linksight::io {

/// {"ball_radius_m", "pitch_m", "neck_radius_m", "neck_length_m", "count"} (`indent` < 0:
/// one line).
[[nodiscard]] std::string chain_json(const ComponentGeometry& geometry, int indent = -1);

}  // namespace linksight::io
