#pragma once
/// @file Base poses per frame (issue 17, part 4): what `linksight render` writes as
/// base_pose.csv (the true pose) and `linksight track --base-prior` reads. One row per
/// frame: the base's pose in the camera frame, X_CB, as `frame,x_m,y_m,z_m,qw,qx,qy,qz`
/// (translation [m], then the rotation as a unit quaternion, w first).

#include <Eigen/Geometry>
#include <cstddef>
#include <filesystem>
#include <ostream>
#include <vector>

namespace linksight::io {

/// The header line, with its newline.
void write_base_pose_header(std::ostream& out);
/// One frame's row.
void write_base_pose_row(std::ostream& out, int frame, const Eigen::Isometry3d& X_CB);

/// One pose per frame 0..frames-1 (rows in any order). Throws InputError naming the file
/// (and the line) for: a column missing, unknown or given twice; a row with the wrong
/// field count; a value that is not a finite number; a quaternion whose norm is not 1
/// within 1e-3 (it is normalized otherwise); a frame that is not an index below `frames`
/// or is given twice; a frame with no row.
[[nodiscard]] std::vector<Eigen::Isometry3d> read_base_poses(const std::filesystem::path& path,
                                                             std::size_t frames);

}  // namespace linksight::io
