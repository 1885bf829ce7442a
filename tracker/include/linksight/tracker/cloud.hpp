#pragma once
/// @file Point cloud type shared by every reader, the simulator and the tracker.

#include <Eigen/Core>
#include <cstddef>
#include <span>
#include <vector>

namespace linksight {

/// Contiguous xyz float32 points in the camera frame C, in metres.
/// May contain non-finite points; the tracker drops and counts them.
struct Cloud {
  std::vector<float> xyz;  ///< x0 y0 z0 x1 y1 z1 ... [m]

  [[nodiscard]] std::size_t size() const { return xyz.size() / 3; }
  [[nodiscard]] bool empty() const { return xyz.empty(); }
  void reserve(std::size_t n) { xyz.reserve(3 * n); }
  void push_back(float x, float y, float z) {
    xyz.push_back(x);
    xyz.push_back(y);
    xyz.push_back(z);
  }
  void push_back(const Eigen::Vector3d& p) {
    push_back(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()));
  }
  [[nodiscard]] Eigen::Vector3d point(std::size_t i) const {
    return {xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]};
  }
};

/// The frame's depth image beside the link's cloud (issue 17, part 3): what the camera saw
/// along every pixel's ray, nearer surfaces and free space alike. Pinhole intrinsics, pixel
/// centres at integers (u right, v down), as io::Intrinsics with no distortion.
struct DepthView {
  int width = 0, height = 0;
  std::span<const float> depth_m;  ///< row-major, along the optical axis [m]; <= 0 or not finite: none
  double fx = 0, fy = 0, cx = 0, cy = 0;  ///< [px]
  /// Throws std::invalid_argument unless there are width x height values (both > 0) and
  /// the focal lengths are finite and > 0, the principal point finite.
  void validate() const;
};

}  // namespace linksight
