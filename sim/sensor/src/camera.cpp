#include "linksight/sim/camera.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

#include "linksight/tracker/format.hpp"
#include "linksight/tracker/limits.hpp"

namespace linksight::sim {

io::Intrinsics sr300_intrinsics() {
  io::Intrinsics k;
  k.width = 640;
  k.height = 480;
  k.fx = k.fy = 473.0;
  k.cx = 310.0;
  k.cy = 245.0;
  k.depth_scale = 0.000125;
  return k;
}

Eigen::Isometry3d look_at(const Eigen::Vector3d& eye_W, const Eigen::Vector3d& target_W,
                          const Eigen::Vector3d& up_W) {
  const Eigen::Vector3d d = target_W - eye_W;
  if (!(d.norm() > 1e-9)) throw std::invalid_argument("look_at: eye and target coincide");
  const Eigen::Vector3d z = d.normalized();
  const Eigen::Vector3d x = z.cross(up_W);  // image right = forward x up
  if (!(x.norm() > 1e-9 * up_W.norm()) || !(up_W.norm() > 0))
    throw std::invalid_argument("look_at: view direction is parallel to up");
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.linear().col(0) = x.normalized();
  X.linear().col(2) = z;
  X.linear().col(1) = z.cross(X.linear().col(0));  // y down
  X.translation() = eye_W;
  return X;
}

void CameraParams::validate() const {
  fields::check(*this, "camera");
  intrinsics.validate();
  if (static_cast<long long>(intrinsics.width) * intrinsics.height > io::kMaxDepthPngPixels)
    fields::fail("camera", "height", intrinsics.height,
                 "makes " +
                     format_shortest(static_cast<double>(intrinsics.width) * intrinsics.height) +
                     " pixels with width " + std::to_string(intrinsics.width) + ", more than " +
                     format_shortest(static_cast<double>(io::kMaxDepthPngPixels)) +
                     " (what a recording's depth PNG may hold)");
  if (!(z_max > z_min))
    fields::fail("camera", "z_max_m", z_max, "must be > z_min_m (" + format_shortest(z_min) + ")");
  const Eigen::Matrix3d R = X_WC.linear();
  if (!(R.transpose() * R).isIdentity(1e-6) || !(R.determinant() > 0) ||
      !X_WC.matrix().row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1)))
    throw fields::FieldError("X_WC", "[...]", "rotation part is not a proper rotation", "camera");
}

}  // namespace linksight::sim
