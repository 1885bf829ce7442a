#include "linksight/sim/sensor_cull.hpp"

#include <algorithm>
#include <cmath>

namespace linksight::sim {

PixelRect grown(const PixelRect& r, int by, int W, int H) {
  if (r.empty()) return {};
  return {{std::max(0, r.u0 - by), std::min(W - 1, r.u1 + by), std::max(0, r.v0 - by),
           std::min(H - 1, r.v1 + by)}};
}

PixelRect reachable(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                    const Eigen::Isometry3d& X_WC, const io::Intrinsics& K, double margin_px) {
  const PixelRect all{{0, K.width - 1, 0, K.height - 1}};
  if (!(lo.array() <= hi.array()).all()) return {};  // nothing in the scene
  if (K.model != io::Distortion::none) return all;
  const Eigen::Isometry3d X_CW = X_WC.inverse();
  double u_min = std::numeric_limits<double>::infinity(), u_max = -u_min;
  double v_min = u_min, v_max = -u_min;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d p_W((c & 1) ? hi.x() : lo.x(), (c & 2) ? hi.y() : lo.y(),
                              (c & 4) ? hi.z() : lo.z());
    const Eigen::Vector3d p_C = X_CW * p_W;
    if (!(p_C.z() > 1e-6)) return all;
    const double u = K.fx * p_C.x() / p_C.z() + K.cx, v = K.fy * p_C.y() / p_C.z() + K.cy;
    u_min = std::min(u_min, u);
    u_max = std::max(u_max, u);
    v_min = std::min(v_min, v);
    v_max = std::max(v_max, v);
  }
  // A pixel's ray passes through (u + du, v + dv): keep u within margin of the projection.
  const auto clamp_to = [](double x, int hi_px) {
    return static_cast<int>(std::clamp(x, -1.0, static_cast<double>(hi_px) + 1));
  };
  return {{clamp_to(std::floor(u_min - margin_px), K.width - 1),
           clamp_to(std::ceil(u_max + margin_px), K.width - 1),
           clamp_to(std::floor(v_min - margin_px), K.height - 1),
           clamp_to(std::ceil(v_max + margin_px), K.height - 1)}};
}

ShadowCaster ShadowCaster::of(const Eigen::AlignedBox3d& box_W, const Eigen::Matrix3d& R_WP,
                              const Eigen::Vector3d& p_WP) {
  ShadowCaster c;
  if (box_W.isEmpty()) {  // an absent body blocks nothing
    c.everywhere = false;
    c.dist2 = std::numeric_limits<float>::infinity();
    return c;
  }
  double x0 = std::numeric_limits<double>::infinity(), x1 = -x0, y0 = x0, y1 = -x0;
  for (int k = 0; k < 8; ++k) {
    const Eigen::Vector3d q =
        R_WP.transpose() * (box_W.corner(static_cast<Eigen::AlignedBox3d::CornerType>(k)) - p_WP);
    if (!(q.z() > 1e-6)) return c;
    x0 = std::min(x0, q.x() / q.z());
    x1 = std::max(x1, q.x() / q.z());
    y0 = std::min(y0, q.y() / q.z());
    y1 = std::max(y1, q.y() / q.z());
  }
  // Margins for the float arithmetic of the test and of the shadow ray's origin
  // (1e-5 m off the surface): 1e-4 on the plane, 1 mm in distance.
  constexpr double kSlack = 1e-4;
  c.everywhere = false;
  c.x0 = static_cast<float>(x0 - kSlack);
  c.x1 = static_cast<float>(x1 + kSlack);
  c.y0 = static_cast<float>(y0 - kSlack);
  c.y1 = static_cast<float>(y1 + kSlack);
  const double d = std::max(0.0, box_W.exteriorDistance(p_WP) - 1e-3);
  c.dist2 = static_cast<float>(d * d);
  return c;
}

}  // namespace linksight::sim
