#pragma once
/// @file The link model of Section III: M+1 points θ = [p_0 … p_M] define M
/// local frames (Eqs. 1–8).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

namespace linksight {

/// Reference vectors / model parameters θ (Eq. 1): M+1 points in the camera frame [m].
using Nodes = std::vector<Eigen::Vector3d>;

/// Below this value of h/d (Eq. 6 over Eq. 4, i.e. sin of the angle between Z and
/// the camera x axis) the paper's X1 = 0 solution is numerically singular.
inline constexpr double kFrameDegenerateSin = 1e-6;

/// Local frame K of one component, as the pose X_CK of K in the camera frame C.
struct ComponentFrame {
  Eigen::Isometry3d X_CK = Eigen::Isometry3d::Identity();
  bool degenerate = false;  ///< true when the continuity rule, not Eq. 5–7, set X
};

/// Frame from p_i and p_{i+1} (Eqs. 3–8). X follows the paper (X1 = 0). When Z is
/// (nearly) parallel to the camera x axis, X1 = 0 has no stable solution; then X is
/// `X_ref` projected onto the plane normal to Z (parallel transport of the
/// neighbouring frame's X), which is continuous in Z. `X_ref` defaults to the
/// camera y axis. Coincident points (d = 0) keep Z = `Z_ref`.
[[nodiscard]] ComponentFrame frame_from_points(
    const Eigen::Vector3d& p_i, const Eigen::Vector3d& p_next,
    const Eigen::Vector3d& X_ref = Eigen::Vector3d::UnitY(),
    const Eigen::Vector3d& Z_ref = Eigen::Vector3d::UnitZ());

/// The M frames of a chain of M+1 nodes. Degenerate frames take X from the previous
/// frame in the chain (or from the next one for frame 0), so X stays continuous
/// along the chain. Throws std::invalid_argument for fewer than 2 nodes.
[[nodiscard]] std::vector<ComponentFrame> frames_from_nodes(const Nodes& nodes);

}  // namespace linksight
