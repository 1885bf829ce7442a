#pragma once
/// @file Pinhole intrinsics of a depth camera, as stored in intrinsics.json.

#include <Eigen/Core>
#include <array>
#include <filesystem>
#include <string>
#include <string_view>

namespace linksight::io {

enum class Distortion {
  none,
  brown_conrady,          ///< coefficients map undistorted → distorted (inverted iteratively)
  inverse_brown_conrady,  ///< coefficients map distorted → undistorted (RealSense SR300 depth)
};
/// "none", "brown_conrady", "inverse_brown_conrady" (intrinsics.json's `model`, a scene's
/// `camera.distortion`); parse throws std::invalid_argument naming the value and choices.
[[nodiscard]] std::string_view to_string(Distortion model);
[[nodiscard]] Distortion parse_distortion(std::string_view name);

/// Pixel coordinates: u right, v down, pixel centres at integers. Camera frame: x right,
/// y down, z forward [m].
struct Intrinsics {
  int width = 640;
  int height = 480;
  double fx = 473.0, fy = 473.0;  ///< focal lengths [px]
  double cx = 310.0, cy = 245.0;  ///< principal point [px]
  double depth_scale = 0.000125;  ///< metres per depth unit (SR300: 1/8 mm)
  Distortion model = Distortion::none;
  std::array<double, 5> coeffs{};  ///< k1, k2, p1, p2, k3 (RealSense order)

  void validate() const;  ///< throws std::invalid_argument naming the field
  /// Camera-frame point [m] of pixel (u, v) at depth z [m] (z along the optical axis).
  [[nodiscard]] Eigen::Vector3d deproject(double u, double v, double z) const;
  /// Pixel of a camera-frame point (inverse of deproject).
  [[nodiscard]] Eigen::Vector2d project(const Eigen::Vector3d& p_C) const;
};

/// Reads intrinsics.json: keys width, height, fx, fy, cx, cy, depth_scale, and
/// optionally model ("none", "brown_conrady", "inverse_brown_conrady") and coeffs
/// (5 numbers). Unknown keys are errors. Throws InputError naming the file and key.
[[nodiscard]] Intrinsics read_intrinsics(const std::filesystem::path& path);
void write_intrinsics(const std::filesystem::path& path, const Intrinsics& intrinsics);
/// The JSON object intrinsics.json holds (`indent` < 0: one line).
[[nodiscard]] std::string intrinsics_json(const Intrinsics& intrinsics, int indent = -1);

}  // namespace linksight::io
