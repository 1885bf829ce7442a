#pragma once
/// @file Scripted pose of the manipulator's active joint (the chain's base) over time.

#include <Eigen/Geometry>
#include <vector>

#include "linksight/tracker/fields.hpp"

namespace linksight::sim {

/// A base pose at a time.
struct Waypoint {
  double t = 0.0;  ///< [s]
  Eigen::Isometry3d X_WB = Eigen::Isometry3d::Identity();
  /// The key of a `waypoints` item (fields.hpp); its pose is read from position_m and
  /// rpy_deg, not a field.
  template <class Archive>
  void fields(Archive& ar) {
    ar("t_s", t, fields::in(0, 1e6));
  }
  void validate() const { fields::check(*this, "waypoint"); }
};

/// A sinusoidal sweep added on top of the waypoints: a rotation about `axis_B` (base
/// frame) by amplitude * sin(2 pi f t + phase), and a translation offset_W * sin(...).
struct Sweep {
  Eigen::Vector3d axis_B = Eigen::Vector3d::UnitZ();
  double amplitude = 0.0;                              ///< [rad]
  Eigen::Vector3d offset_W = Eigen::Vector3d::Zero();  ///< [m]
  double frequency = 0.5;                              ///< [Hz]
  double phase = 0.0;                                  ///< [rad]
  /// The keys of a `sweeps` item (fields.hpp).
  template <class Archive>
  void fields(Archive& ar) {
    ar("axis", axis_B);  // not zero
    ar("amplitude_deg", amplitude, fields::deg(fields::in(-180, 180)));
    ar("offset_m", offset_W);
    ar("frequency_hz", frequency, fields::in(0, 100));
    ar("phase_deg", phase, fields::deg(fields::in(-360, 360)));
  }
  void validate() const;  ///< throws fields::FieldError naming the key
};

/// Linear interpolation of position and slerp of orientation between waypoints (held
/// before the first and after the last), plus any sweeps.
class BaseTrajectory {
 public:
  BaseTrajectory() = default;  ///< identity, forever
  /// Throws std::invalid_argument unless the times strictly increase and every waypoint
  /// and sweep is valid (validate()).
  explicit BaseTrajectory(std::vector<Waypoint> waypoints, std::vector<Sweep> sweeps = {});
  [[nodiscard]] Eigen::Isometry3d pose(double t) const;  ///< X_WB(t)
  [[nodiscard]] bool empty() const { return waypoints_.empty() && sweeps_.empty(); }

 private:
  std::vector<Waypoint> waypoints_;
  std::vector<Sweep> sweeps_;
};

}  // namespace linksight::sim
