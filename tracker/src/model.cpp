#include "linksight/tracker/model.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace linksight {
namespace {

// Unit vector normal to Z nearest to `ref`, or a fixed axis if `ref` is parallel to Z.
Eigen::Vector3d normal_part(const Eigen::Vector3d& ref, const Eigen::Vector3d& Z) {
  Eigen::Vector3d v = ref - ref.dot(Z) * Z;
  if (v.norm() < 1e-9) {
    const Eigen::Vector3d alt =
        std::abs(Z.y()) < 0.9 ? Eigen::Vector3d::UnitY() : Eigen::Vector3d::UnitZ();
    v = alt - alt.dot(Z) * Z;
  }
  return v.normalized();
}

// `v` rotated by the minimal rotation taking unit `a` to unit `b` (Rodrigues).
Eigen::Vector3d carry(const Eigen::Vector3d& v, const Eigen::Vector3d& a,
                      const Eigen::Vector3d& b) {
  const double c = a.dot(b);
  if (c < -1.0 + 1e-12) {  // opposite: any half turn about an axis normal to a
    const Eigen::Vector3d u = a.unitOrthogonal();
    return -v + 2.0 * v.dot(u) * u;
  }
  const Eigen::Vector3d k = a.cross(b);
  return v * c + k.cross(v) + k * (k.dot(v) / (1.0 + c));
}

ComponentFrame make_frame(const Eigen::Vector3d& p, const Eigen::Vector3d& X,
                          const Eigen::Vector3d& Z, bool carried) {
  ComponentFrame f;
  f.X_CK.linear().col(0) = X;
  f.X_CK.linear().col(1) = Z.cross(X);  // Eq. (7)
  f.X_CK.linear().col(2) = Z;
  f.X_CK.translation() = p;  // Eq. (2)
  f.carried = carried;
  return f;
}

Eigen::Vector3d z_axis(const Eigen::Vector3d& p_i, const Eigen::Vector3d& p_next,
                       const Eigen::Vector3d& Z_ref, bool& coincident) {
  const Eigen::Vector3d delta = p_next - p_i;
  const double d = delta.norm();  // Eq. (4)
  coincident = !(d > 0.0 && std::isfinite(d));
  return coincident ? Eigen::Vector3d(Z_ref.normalized()) : Eigen::Vector3d(delta / d);  // Eq. (3)
}

}  // namespace

ComponentFrame frame_from_points(const Eigen::Vector3d& p_i, const Eigen::Vector3d& p_next,
                                 const Eigen::Vector3d& X_ref, const Eigen::Vector3d& Z_ref) {
  bool coincident = false;
  const Eigen::Vector3d Z = z_axis(p_i, p_next, Z_ref, coincident);
  const double h_over_d = std::hypot(Z.y(), Z.z());  // Eq. (6) / d: sin of angle to camera x
  const double s_carry = std::sin(kFrameCarryAngle), s_paper = std::sin(kFramePaperAngle);
  if (h_over_d >= s_paper) {
    // Eq. (5) with X1 = 0: X = (0, Z3, -Z2) / sqrt(Z2^2 + Z3^2).
    return make_frame(p_i, Eigen::Vector3d(0.0, Z.z(), -Z.y()) / h_over_d, Z, coincident);
  }
  const Eigen::Vector3d X_carry = normal_part(X_ref, Z);
  if (h_over_d <= s_carry) return make_frame(p_i, X_carry, Z, true);
  // Turn from the carried X to Eq. 5 about Z, by a smoothstep of the angle, so X is
  // continuous at both ends of the band.
  const Eigen::Vector3d X_paper = Eigen::Vector3d(0.0, Z.z(), -Z.y()) / h_over_d;
  const double theta = std::atan2(X_carry.cross(X_paper).dot(Z), X_carry.dot(X_paper));
  const double t = (h_over_d - s_carry) / (s_paper - s_carry);
  const double w = t * t * (3.0 - 2.0 * t);
  const Eigen::Vector3d X = Eigen::AngleAxisd(w * theta, Z) * X_carry;
  return make_frame(p_i, X.normalized(), Z, true);
}

std::vector<ComponentFrame> frames_from_nodes(const Nodes& nodes) {
  if (nodes.size() < 2) {
    throw std::invalid_argument("frames_from_nodes: need at least 2 nodes, got " +
                                std::to_string(nodes.size()));
  }
  const std::size_t m = nodes.size() - 1;
  std::vector<ComponentFrame> frames;
  frames.reserve(m);
  frames.push_back(frame_from_points(nodes[0], nodes[1]));
  for (std::size_t i = 1; i < m; ++i) {
    const Eigen::Vector3d Z_prev = frames[i - 1].X_CK.linear().col(2);
    const Eigen::Vector3d X_prev = frames[i - 1].X_CK.linear().col(0);
    bool coincident = false;
    const Eigen::Vector3d Z = z_axis(nodes[i], nodes[i + 1], Z_prev, coincident);
    const Eigen::Vector3d X = normal_part(carry(X_prev, Z_prev, Z), Z);
    frames.push_back(make_frame(nodes[i], X, Z, true));
  }
  return frames;
}

}  // namespace linksight
