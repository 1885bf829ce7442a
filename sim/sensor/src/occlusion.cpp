#include "linksight/sim/occlusion.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

namespace linksight::sim {

std::string_view to_string(OcclusionSite site) {
  return site == OcclusionSite::middle ? "middle" : "tip";
}

OcclusionSite parse_occlusion_site(std::string_view name) {
  if (name == "middle") return OcclusionSite::middle;
  if (name == "tip") return OcclusionSite::tip;
  throw std::invalid_argument("unknown occlusion site '" + std::string(name) +
                              "' (expected middle or tip)");
}

void ScreenOcclusion::validate() const {
  fields::check(*this, "occlusion");
  if (!(to_s > from_s))
    fields::fail("occlusion", "to_s", to_s, "must be > from_s (" + format_shortest(from_s) + ")");
}

namespace {
constexpr double kHalfThickness = 0.005;  // of the board [m]
constexpr double kClearance = 0.002;      // between the board's back face and the balls [m]
}  // namespace

Occluder screen_occluder(const ScreenOcclusion& o, const ComponentGeometry& chain,
                         const BaseTrajectory& base, const CameraParams& camera,
                         double duration_s) {
  o.validate();
  if (!(o.fraction > 0)) fields::fail("occlusion", "fraction", o.fraction, "must be > 0 for a board");
  // The board must clear the link's front, or the balls poke through and it hides less.
  const double min_gap =
      std::max(chain.ball_radius, chain.neck_radius) + kHalfThickness + kClearance;
  if (!(o.gap >= min_gap))
    fields::fail("occlusion", "gap_m", o.gap,
                 "must be >= " + format_shortest(min_gap) + " m, so the board clears the balls");
  if (!(o.from_s < duration_s))
    fields::fail("occlusion", "from_s", o.from_s,
                 "must be < duration_s (" + format_shortest(duration_s) +
                     "), or the board never appears");
  // The link in the base frame B: ball k at (k d, 0, 0). Its silhouette runs from the
  // back of ball 0 to the end of the last component's neck.
  const double d = chain.pitch, r = chain.ball_radius;
  const double s_begin = -r;
  const double s_end = (chain.count - 1) * d + std::max(r, chain.neck_length + chain.neck_radius);
  const double length = s_end - s_begin;
  double s0 = 0, s1 = 0;
  if (o.at == ScreenOcclusion::Where::middle) {
    const double mid = 0.5 * (s_begin + s_end);
    s0 = mid - 0.5 * o.fraction * length;
    s1 = mid + 0.5 * o.fraction * length;
  } else {
    // Over the tip end and beyond it, so the tip is hidden whatever the box's thickness.
    s0 = s_end - o.fraction * length;
    s1 = s_end + 2 * r;
  }
  const Eigen::Isometry3d X_WB = base.pose(o.from_s);
  const Eigen::Vector3d q0 = X_WB * Eigen::Vector3d(s0, 0, 0);
  const Eigen::Vector3d q1 = X_WB * Eigen::Vector3d(s1, 0, 0);
  const Eigen::Vector3d q_mid = 0.5 * (q0 + q1);
  const Eigen::Vector3d eye = camera.X_WC.translation();
  const double dist = (q_mid - eye).norm();
  const Eigen::Vector3d w = (q_mid - eye) / dist;  // viewing direction to the hidden part
  // Both ends of the hidden part must lie beyond the board's plane, seen from the camera.
  if (!(w.dot(camera.X_WC.linear().col(2)) > 0) || !((q0 - eye).dot(w) > o.gap) ||
      !((q1 - eye).dot(w) > o.gap))
    throw std::invalid_argument("the link at from_s = " + std::to_string(o.from_s) +
                                " s is not in front of the camera, beyond gap_m");
  // The box lies in the plane through q_mid - gap w with normal w; the hidden interval's
  // ends are where the camera rays to q0 and q1 cross that plane.
  const Eigen::Vector3d centre_plane = q_mid - o.gap * w;
  auto on_plane = [&](const Eigen::Vector3d& q) {
    return Eigen::Vector3d(eye + (q - eye) * ((centre_plane - eye).dot(w) / (q - eye).dot(w)));
  };
  const Eigen::Vector3d a0 = on_plane(q0), a1 = on_plane(q1);
  const Eigen::Vector3d x = (a1 - a0).normalized();
  const Eigen::Vector3d y = w.cross(x).normalized();
  Eigen::Isometry3d X_WO = Eigen::Isometry3d::Identity();
  X_WO.linear().col(0) = x;
  X_WO.linear().col(1) = y;
  X_WO.linear().col(2) = x.cross(y);
  X_WO.translation() = 0.5 * (a0 + a1);
  const double scale = (centre_plane - eye).norm() / dist;  // link distance -> box distance

  Occluder occ;
  occ.shape.kind = Shape::Kind::box;
  occ.shape.half_extents = {0.5 * (a1 - a0).norm(), 0.5 * o.height * scale, kHalfThickness};
  occ.from_s = o.from_s;
  occ.to_s = o.to_s;
  const Eigen::Isometry3d X_BO = X_WB.inverse() * X_WO;
  std::vector<Waypoint> path;
  if (o.follow_base) {
    // At every camera frame in the window: the sensor renders only there.
    const int first = static_cast<int>(std::ceil(o.from_s * camera.fps - 1e-9));
    for (int f = first;; ++f) {
      const double t = f / camera.fps;
      if (t >= o.to_s || t > duration_s) break;
      path.push_back({t, base.pose(t) * X_BO});
    }
  }
  if (path.empty()) path.push_back({o.from_s, X_WO});
  occ.path = BaseTrajectory(std::move(path));
  return occ;
}

}  // namespace linksight::sim
