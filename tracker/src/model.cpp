#include "linksight/tracker/model.hpp"

#include <cmath>
#include <stdexcept>

namespace linksight {

ComponentFrame frame_from_points(const Eigen::Vector3d& p_i, const Eigen::Vector3d& p_next,
                                 const Eigen::Vector3d& X_ref, const Eigen::Vector3d& Z_ref) {
  ComponentFrame out;
  const Eigen::Vector3d delta = p_next - p_i;
  const double d = delta.norm();  // Eq. (4)
  Eigen::Vector3d Z;
  if (d > 0.0 && std::isfinite(d)) {
    Z = delta / d;  // Eq. (3)
  } else {
    Z = Z_ref.normalized();
    out.degenerate = true;
  }
  const double h_over_d = std::hypot(Z.y(), Z.z());  // Eq. (6) divided by d
  Eigen::Vector3d X;
  if (!out.degenerate && h_over_d >= kFrameDegenerateSin) {
    // Eq. (5) with X1 = 0: X = (0, Z3, -Z2) / sqrt(Z2² + Z3²).
    X = Eigen::Vector3d(0.0, Z.z(), -Z.y()) / h_over_d;
  } else {
    // Z ∥ camera x: X1 = 0 leaves X undetermined. Transport the reference X onto the
    // plane normal to Z; the projection is continuous in Z, so neighbouring frames stay
    // close. If the reference is itself parallel to Z, fall back to a fixed axis.
    out.degenerate = true;
    Eigen::Vector3d ref = X_ref - X_ref.dot(Z) * Z;
    if (ref.norm() < 1e-9) {
      const Eigen::Vector3d alt =
          std::abs(Z.y()) < 0.9 ? Eigen::Vector3d::UnitY() : Eigen::Vector3d::UnitZ();
      ref = alt - alt.dot(Z) * Z;
    }
    X = ref.normalized();
  }
  const Eigen::Vector3d Y = Z.cross(X);  // Eq. (7)
  out.X_CK.linear().col(0) = X;
  out.X_CK.linear().col(1) = Y;
  out.X_CK.linear().col(2) = Z;
  out.X_CK.translation() = p_i;  // Eq. (2)
  return out;
}

std::vector<ComponentFrame> frames_from_nodes(const Nodes& nodes) {
  if (nodes.size() < 2) {
    throw std::invalid_argument("frames_from_nodes: need at least 2 nodes, got " +
                                std::to_string(nodes.size()));
  }
  const std::size_t m = nodes.size() - 1;
  std::vector<ComponentFrame> frames(m);
  for (std::size_t i = 0; i < m; ++i) frames[i] = frame_from_points(nodes[i], nodes[i + 1]);
  // Degenerate frames: transport X from the nearest regular neighbour (previous first,
  // then next), so a run of degenerate frames inherits one X continuously.
  for (std::size_t i = 0; i < m; ++i) {
    if (!frames[i].degenerate) continue;
    const Eigen::Vector3d Z_ref =
        i > 0 ? frames[i - 1].X_CK.linear().col(2).eval() : Eigen::Vector3d::UnitZ().eval();
    Eigen::Vector3d X_ref = Eigen::Vector3d::UnitY();
    if (i > 0) {
      X_ref = frames[i - 1].X_CK.linear().col(0);
    } else {
      for (std::size_t k = 1; k < m; ++k) {
        if (!frames[k].degenerate) {
          X_ref = frames[k].X_CK.linear().col(0);
          break;
        }
      }
    }
    frames[i] = frame_from_points(nodes[i], nodes[i + 1], X_ref, Z_ref);
  }
  return frames;
}

}  // namespace linksight
