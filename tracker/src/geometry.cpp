#include "linksight/tracker/geometry.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace linksight {
void ComponentGeometry::validate() const {
  fields::check(*this, "geometry");
  if (!(pitch > ball_radius))
    fields::fail("geometry", "pitch_m", pitch, "must be > ball_radius_m (" + format_shortest(ball_radius) + ")");
  if (!(neck_radius < ball_radius))
    fields::fail("geometry", "neck_radius_m", neck_radius,
                 "must be < ball_radius_m (" + format_shortest(ball_radius) + ")");
  if (!(neck_length <= pitch))
    fields::fail("geometry", "neck_length_m", neck_length, "must be <= pitch_m (" + format_shortest(pitch) + ")");
}

double ComponentGeometry::sdf(const Eigen::Vector3d& p_K) const {
  const double ball = p_K.norm() - ball_radius;
  // Capsule around the segment [0, neck_length] on +Z.
  const double t = std::clamp(p_K.z(), 0.0, neck_length);
  const double neck = (p_K - Eigen::Vector3d(0, 0, t)).norm() - neck_radius;
  return std::min(ball, neck);
}

}  // namespace linksight
