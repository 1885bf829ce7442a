#pragma once
/// @file The sensor's culling stage: which pixels' rays can reach a body, and which shadow
/// rays a body can block. Exact by construction: a culled ray provably misses; the images
/// are the same with culling off (SensorParams::cull), only slower.

#include <Eigen/Geometry>
#include <limits>

#include "linksight/io/intrinsics.hpp"
#include "linksight/sim/camera.hpp"

namespace linksight::sim {

/// Rays are cast in packets of this many neighbouring pixels of a row.
inline constexpr int kRayPacket = 16;

/// A PixelBox that packets can be tested against. Its bounds may lie one pixel outside the
/// image (reachable() clamps to [-1, size]).
struct PixelRect : PixelBox {
  /// Whether the pixels (u, v) ... (u + kRayPacket - 1, v) of a packet reach into it.
  [[nodiscard]] bool touches(int u, int v) const {
    return v >= v0 && v <= v1 && u + kRayPacket - 1 >= u0 && u <= u1;
  }
};

/// `r` grown by `by` pixels each way, clipped to a W x H image; empty stays empty.
[[nodiscard]] PixelRect grown(const PixelRect& r, int by, int W, int H);

/// The pixels whose rays, jittered by at most `margin_px`, can reach the world box
/// [lo, hi] (empty when lo > hi). A pinhole ray reaches the box only if it passes inside
/// the box's projection, and the projection of a convex body lies in the hull of its
/// corners' projections. The whole image when that does not hold: a corner at or behind
/// the camera plane, or a distorted camera.
[[nodiscard]] PixelRect reachable(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                                  const Eigen::Isometry3d& X_WC, const io::Intrinsics& K,
                                  double margin_px);

/// A body that may cast a projector shadow, seen from the projector P: the bounds of its
/// silhouette on the projector's z = 1 plane and its least distance from the projector.
/// A segment from p to the projector meets the body only if p projects inside the
/// silhouette (the segment's points all project onto p) and p is farther than the body.
struct ShadowCaster {
  float x0 = -std::numeric_limits<float>::infinity(), x1 = -x0, y0 = x0, y1 = x1;
  float dist2 = 0;  ///< squared least distance [m^2]
  bool everywhere = true;  ///< a corner at or behind the projector plane: no silhouette bound

  /// The caster of the world box `box_W` (empty: blocks nothing) for a projector at p_WP
  /// with orientation R_WP (z along its optical axis).
  [[nodiscard]] static ShadowCaster of(const Eigen::AlignedBox3d& box_W,
                                       const Eigen::Matrix3d& R_WP, const Eigen::Vector3d& p_WP);
  /// Whether a shadow ray from q (its start in the projector's frame) may be blocked.
  // Forced inline: GCC's inlining in the cast loop moves with the other files of sim/sensor's
  // unity unit; after b198ad8 it left this out, 6% more instructions in the cast's own code
  // (callgrind; bench/README.md).
  [[nodiscard, gnu::always_inline]] bool may_block(const Eigen::Vector3f& q) const {
    if (everywhere) return true;
    if (q.squaredNorm() <= dist2) return false;
    if (!(q.z() > 0)) return true;  // beside or behind the projector: no silhouette test
    const float x = q.x() / q.z(), y = q.y() / q.z();
    return x >= x0 && x <= x1 && y >= y0 && y <= y1;
  }
};

}  // namespace linksight::sim
