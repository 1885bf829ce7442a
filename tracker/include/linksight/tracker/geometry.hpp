#pragma once
/// @file Component geometry: the one source of truth for the link's shape
/// (SDF metric now; meshes, collision and ground truth in the simulator).

#include <Eigen/Core>

#include "linksight/tracker/fields.hpp"

namespace linksight {

/// One rigid ball-and-socket component of the deformable link, in its local
/// frame K: origin at the ball centre, +Z toward the next ball (paper Fig. 2).
/// All lengths in metres.
struct ComponentGeometry {
  double ball_radius = 0.015;  ///< r: radius of the ball [m]
  double pitch = 0.045;        ///< d: ball-centre to ball-centre distance [m]
  double neck_radius = 0.007;  ///< radius of the neck/socket capsule [m]
  double neck_length = 0.030;  ///< capsule axis length from the ball centre along +Z [m]
  int count = 11;              ///< number of components in the link

  /// The keys of a scene's `chain` block (fields.hpp).
  template <class Archive>
  void fields(Archive& ar) {
    ar("ball_radius_m", ball_radius, fields::in(1e-4, 1));
    ar("pitch_m", pitch, fields::in(1e-4, 1));
    ar("neck_radius_m", neck_radius, fields::in(1e-4, 1));
    ar("neck_length_m", neck_length, fields::in(0, 1));
    ar("count", count, fields::in(1, 100));
  }
  /// Throws fields::FieldError naming the offending key.
  void validate() const;

  /// Signed distance [m] from a point in the component frame K to the surface of
  /// ball ∪ neck capsule: negative inside, positive outside (paper Sec. VI).
  [[nodiscard]] double sdf(const Eigen::Vector3d& p_K) const;
};

}  // namespace linksight
