#pragma once
/// @file The simulated depth camera: intrinsics, range, rate and pose X_WC.

#include <Eigen/Geometry>

#include "linksight/io/intrinsics.hpp"
#include "linksight/tracker/fields.hpp"
#include "linksight/tracker/limits.hpp"

namespace linksight::sim {

/// Intrinsics of an Intel RealSense SR300 depth stream at 640x480: fx = fy = 473,
/// (cx, cy) = (310, 245) px (about 68 x 54 degrees field of view), depth unit 1/8 mm.
/// Source: the SR300 datasheet's 640x480 depth mode and the intrinsics RealSense reports
/// for SR300/SR305 units (see tests/data/sr305/intrinsics.json). No distortion by
/// default; `inverse_brown_conrady` is available in io::Intrinsics.
[[nodiscard]] io::Intrinsics sr300_intrinsics();

/// Pose of a camera at `eye_W` looking at `target_W`, with image "up" (-y of C) as close
/// to `up_W` as possible. Camera frame C: x right, y down, z forward. Throws
/// std::invalid_argument when eye == target or the view direction is parallel to up.
[[nodiscard]] Eigen::Isometry3d look_at(const Eigen::Vector3d& eye_W,
                                        const Eigen::Vector3d& target_W,
                                        const Eigen::Vector3d& up_W = Eigen::Vector3d::UnitZ());

/// Pixels [u0, u1] x [v0, v1], inclusive; empty when u0 > u1 or v0 > v1.
struct PixelBox {
  int u0 = 0, u1 = -1, v0 = 0, v1 = -1;
  [[nodiscard]] bool empty() const { return u0 > u1 || v0 > v1; }
  [[nodiscard]] bool contains(int u, int v) const {
    return v >= v0 && v <= v1 && u >= u0 && u <= u1;
  }
  friend bool operator==(const PixelBox&, const PixelBox&) = default;
};

struct CameraParams {
  io::Intrinsics intrinsics = sr300_intrinsics();
  /// Pose of the camera C in the world W. Default: 0.6 m in front of a chain that leaves
  /// a base at (0, 0, 0.5) along +x, looking at its middle.
  Eigen::Isometry3d X_WC = look_at({0.25, -0.6, 0.6}, {0.25, 0.0, 0.45});
  double fps = 30.0;   ///< frame rate [1/s] (SR300: 30 or 60)
  double z_min = 0.2;  ///< nearest valid depth [m] (SR300: 0.2)
  double z_max = 1.5;  ///< farthest valid depth [m] (SR300: 1.5)
  /// The keys of the scene's `camera` block (fields.hpp); `preset` and `look_at` there
  /// are read, not fields (look_at sets X_WC).
  template <class Archive>
  void fields(Archive& ar) {
    io::Intrinsics& k = intrinsics;
    ar("fps", fps, fields::in(1, 1000));
    // What the depth PNG reader takes back (limits.hpp): a recording must read.
    ar("width", k.width, fields::in(1, static_cast<double>(io::kMaxDepthPngSide)));
    ar("height", k.height, fields::in(1, static_cast<double>(io::kMaxDepthPngSide)));
    ar("fx", k.fx, fields::in(1e-3, 1e5));
    ar("fy", k.fy, fields::in(1e-3, 1e5));
    ar("cx", k.cx, fields::in(-1e5, 1e5));
    ar("cy", k.cy, fields::in(-1e5, 1e5));
    ar("depth_scale_m", k.depth_scale, fields::in(1e-7, 1));
    ar("distortion", k.model, io::parse_distortion);
    ar("coeffs", k.coeffs);
    ar("z_min_m", z_min, fields::in(0, 100));
    ar("z_max_m", z_max, fields::in(0, 100));  // and > z_min_m
    ar("X_WC", X_WC);
  }
  /// Throws fields::FieldError naming the key (fx <= 0, zero resolution, z_min >= z_max,
  /// a non-rigid X_WC, ...).
  void validate() const;
};

}  // namespace linksight::sim
