#pragma once
/// @file The link model of Section III: M+1 points θ = [p_0 … p_M] define M
/// local frames (Eqs. 1–8).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

namespace linksight {

/// Reference vectors / model parameters θ (Eq. 1): M+1 points in the camera frame [m].
using Nodes = std::vector<Eigen::Vector3d>;

/// Within this angle of the camera x axis X1 = 0 (Eq. 5) is ill-conditioned (X turns
/// half a circle as Z circles the axis) and undefined on it: X is the carried reference.
inline constexpr double kFrameCarryAngle = 10.0 * 3.14159265358979323846 / 180.0;  // [rad]
/// From kFrameCarryAngle to this angle, X turns smoothly from the carried reference to
/// Eq. 5; beyond it X is the paper's.
inline constexpr double kFramePaperAngle = 20.0 * 3.14159265358979323846 / 180.0;  // [rad]

/// Local frame K of one component, as the pose X_CK of K in the camera frame C.
struct ComponentFrame {
  Eigen::Isometry3d X_CK = Eigen::Isometry3d::Identity();
  bool carried = false;  ///< X (partly) from the reference, not Eq. 5 alone
};

/// Frame from p_i and p_{i+1} (Eqs. 2-8): origin p_i, Z toward p_{i+1} (Eq. 3), X by
/// Eq. 5 (X1 = 0), Y = Z x X (Eq. 7). Near the camera x axis, where Eq. 5 divides by
/// h -> 0, X is `X_ref` projected normal to Z, blended into Eq. 5 between
/// kFrameCarryAngle and kFramePaperAngle, so X stays continuous as Z passes through
/// the axis. Coincident points (d = 0) take Z = `Z_ref`.
[[nodiscard]] ComponentFrame frame_from_points(
    const Eigen::Vector3d& p_i, const Eigen::Vector3d& p_next,
    const Eigen::Vector3d& X_ref = Eigen::Vector3d::UnitY(),
    const Eigen::Vector3d& Z_ref = Eigen::Vector3d::UnitZ());

/// The M frames of a chain of M+1 nodes. Frame 0 is frame_from_points(p_0, p_1). Each
/// later frame has Z by Eq. 3 and the previous frame's X carried by the minimal rotation
/// from Z_{i-1} to Z_i (a rotation-minimizing frame). X therefore turns between
/// neighbours only by the joint's bend. Eq. 5 alone would turn it by up to 180 degrees
/// near the camera x axis. X does not affect the SDF (the component is symmetric about Z).
/// Throws std::invalid_argument for fewer than 2 nodes.
[[nodiscard]] std::vector<ComponentFrame> frames_from_nodes(const Nodes& nodes);

}  // namespace linksight
