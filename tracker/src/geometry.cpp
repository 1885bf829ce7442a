#include "linksight/tracker/geometry.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace linksight {
namespace {
void require(bool ok, const char* field, double value, const char* rule) {
  if (!ok) {
    throw std::invalid_argument("ComponentGeometry." + std::string(field) + " = " +
                                std::to_string(value) + ": " + rule);
  }
}
}  // namespace

void ComponentGeometry::validate() const {
  require(std::isfinite(ball_radius) && ball_radius > 0, "ball_radius", ball_radius, "must be > 0");
  require(std::isfinite(pitch) && pitch > ball_radius, "pitch", pitch, "must be > ball_radius");
  require(std::isfinite(neck_radius) && neck_radius > 0 && neck_radius < ball_radius, "neck_radius",
          neck_radius, "must be in (0, ball_radius)");
  require(std::isfinite(neck_length) && neck_length >= 0 && neck_length <= pitch, "neck_length",
          neck_length, "must be in [0, pitch]");
  require(count >= 1, "count", count, "must be >= 1");
}

double ComponentGeometry::sdf(const Eigen::Vector3d& p_K) const {
  const double ball = p_K.norm() - ball_radius;
  // Capsule around the segment [0, neck_length] on +Z.
  const double t = std::clamp(p_K.z(), 0.0, neck_length);
  const double neck = (p_K - Eigen::Vector3d(0, 0, t)).norm() - neck_radius;
  return std::min(ball, neck);
}

}  // namespace linksight
