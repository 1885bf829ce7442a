#pragma once
/// @file The preloaded ball-and-socket chain in Bullet (paper Sec. I, Fig. 1): the source
/// of ground truth. World frame W: z up. The chain hangs off a kinematic base B (the
/// manipulator's active joint); at rest it leaves B along B's +x.

#include <Eigen/Geometry>
#include <memory>
#include <vector>

#include "linksight/sim/trajectory.hpp"
#include "linksight/tracker/fields.hpp"
#include "linksight/tracker/geometry.hpp"
#include "linksight/tracker/model.hpp"

namespace linksight::sim {

/// The physical chain. Lengths in metres, masses in kg, forces in N.
struct ChainParams {
  ComponentGeometry geometry;
  /// One component: an aluminium ball of r = 15 mm (38 g) plus neck and socket, rounded.
  double component_mass = 0.05;
  /// Preload between socket and ball. The default holds the chain's own weight in any
  /// pose with a margin of 1.67 over the worst case (horizontal chain, base joint):
  /// 0.3 * 450 N * 0.015 m = 2.03 N m against 55 * 0.05 kg * 9.81 m/s^2 * 0.045 m = 1.21 N m.
  double preload_force = 450.0;
  double friction_coefficient = 0.3;                          ///< socket-ball Coulomb friction
  double cone_limit = 25.0 * 3.14159265358979323846 / 180.0;  ///< max bend per joint [rad]

  /// Friction torque that holds each joint: mu * F_preload * r [N m].
  [[nodiscard]] double holding_torque() const;
  /// Gravity torque at the base joint with the chain horizontal: the worst case [N m].
  [[nodiscard]] double worst_gravity_torque(double g = 9.81) const;
  /// The keys of the scene's `chain` block (fields.hpp): the geometry's, then these.
  template <class Archive>
  void fields(Archive& ar) {
    geometry.fields(ar);
    ar("component_mass_kg", component_mass, fields::in(1e-6, 100));
    ar("preload_n", preload_force, fields::in(0, 1e6));
    ar("friction", friction_coefficient, fields::in(0, 10));
    ar("cone_limit_deg", cone_limit, fields::deg(fields::in(0.1, 89.9)));
  }
  /// Throws fields::FieldError naming the key.
  void validate() const;
};

struct WorldParams {
  double dt = 0.001;  ///< physics step [s] (1 kHz)
  bool gravity = true;
  double g = 9.81;        ///< [m/s^2], along -z of W
  /// The keys of the scene's `world` block (fields.hpp).
  template <class Archive>
  void fields(Archive& ar) {
    ar("dt_s", dt, fields::in(1e-5, 0.01));
    ar("gravity", gravity);
    ar("g", g, fields::in(0, 100));
  }
  void validate() const;  ///< throws fields::FieldError naming the key
};

/// A force on one component's ball centre, and a torque on it, over a time window.
struct ForceAction {
  int component = 0;
  Eigen::Vector3d force_W = Eigen::Vector3d::Zero();   ///< [N]
  Eigen::Vector3d torque_W = Eigen::Vector3d::Zero();  ///< [N m]
  double t_start = 0.0, t_end = 0.0;                   ///< [s], active on [t_start, t_end)
  /// The keys of an `actions.forces` item (fields.hpp).
  template <class Archive>
  void fields(Archive& ar) {
    ar("component", component, fields::in(0, 99));  // and < the chain's count
    ar("force_n", force_W);
    ar("torque_nm", torque_W);
    ar("t_start_s", t_start, fields::in(0, 1e6));
    ar("t_end_s", t_end, fields::in(0, 1e6));  // and >= t_start_s
  }
  /// Throws fields::FieldError naming the key; `component_count`: the chain's.
  void validate(int component_count) const;
};

/// Gravity switched on or off at a time.
struct GravityAction {
  double t = 0.0;  ///< [s]
  bool on = true;
  /// The keys of an `actions.gravity` item (fields.hpp).
  template <class Archive>
  void fields(Archive& ar) {
    ar("t_s", t, fields::in(0, 1e6));
    ar("on", on);
  }
  void validate() const { fields::check(*this, "gravity"); }
};

/// A kinematic pusher: a sphere (length 0) or a capsule along its local z, moved along a
/// scripted pose path, pressing on whatever it meets.
struct PusherParams {
  double radius = 0.01;  ///< [m]
  double length = 0.0;   ///< capsule's cylinder length [m]; 0: a sphere
  BaseTrajectory path;   ///< pose of the pusher in W over time
  /// The keys of an `actions.pushers` item (fields.hpp); its `path` is read, not a field.
  template <class Archive>
  void fields(Archive& ar) {
    ar("radius_m", radius, fields::in(1e-4, 1));
    ar("length_m", length, fields::in(0, 2));
  }
  void validate() const;  ///< throws fields::FieldError naming the key
};

/// A static box the chain can be pressed against.
struct ObstacleParams {
  Eigen::Vector3d half_extents = Eigen::Vector3d(0.05, 0.05, 0.05);  ///< [m]
  Eigen::Isometry3d X_WO = Eigen::Isometry3d::Identity();
  /// The key of an `actions.obstacles` item (fields.hpp); the pose is read from
  /// position_m and rpy_deg.
  template <class Archive>
  void fields(Archive& ar) {
    ar("half_extents_m", half_extents);  // all > 0
  }
  void validate() const;  ///< throws fields::FieldError naming the key
};

/// The truth of one instant.
struct Truth {
  double t = 0.0;  ///< [s]
  /// The 11 ball centres and the tip point one pitch beyond the last along its axis:
  /// the M+1 = 12 reference points the tracker estimates (Eq. 1) [m, W].
  Nodes nodes_W;
  std::vector<Eigen::Isometry3d> X_WK;  ///< component frames: origin ball centre, Z toward the next
  /// The base (the flange): ball 0's centre at its origin, component 0 along its +X when
  /// joint 0 is straight.
  Eigen::Isometry3d X_WB = Eigen::Isometry3d::Identity();
  std::vector<double> joint_angles;     ///< 3 per joint (bend y, bend z, twist) [rad]
  bool contact = false;                 ///< anything touches the chain
};

/// Bullet model: per joint three revolute axes with friction motors (max impulse =
/// holding torque * dt) under the MLCP solver, which hold the chain to 0.1 mm where
/// Bullet's spherical-joint motor does not.
class World {
 public:
  World(const ChainParams& chain, const WorldParams& world, const Eigen::Isometry3d& X_WB);
  ~World();
  World(const World&) = delete;
  World& operator=(const World&) = delete;

  /// Moves the kinematic base (the manipulator flange) to X_WB now.
  void set_base_pose(const Eigen::Isometry3d& X_WB);
  /// From now on each step puts the base at trajectory.pose(t + dt). A kinematic base:
  /// its velocity enters contacts, its acceleration does not load the joints.
  void set_base_trajectory(const BaseTrajectory& trajectory);
  void add_force(const ForceAction& action);  ///< validates the action (throws)
  void add_gravity_switch(const GravityAction& action);
  void add_pusher(const PusherParams& pusher);
  void add_obstacle(const ObstacleParams& obstacle);
  /// Largest bend between neighbours (or of component 0 against the base) now [rad].
  [[nodiscard]] double max_bend() const;
  void step();  ///< one physics step of WorldParams::dt
  /// Steps until the nearest step to `t` [s] (no step when time() is already there).
  void step_until(double t);
  [[nodiscard]] double time() const;
  [[nodiscard]] Truth truth() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace linksight::sim
