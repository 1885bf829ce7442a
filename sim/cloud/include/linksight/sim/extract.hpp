#pragma once
/// @file From a depth frame to the tracker's cloud: the paper's preprocessing
/// (Sec. IV.C). Deprojection goes through io::depth_to_cloud, the code that reads real
/// depth PNGs, so a simulated frame and a real one become clouds the same way.

#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <string>

#include "linksight/io/depth_png.hpp"
#include "linksight/io/intrinsics.hpp"
#include "linksight/sim/sensor.hpp"
#include "linksight/tracker/cloud.hpp"

namespace linksight::sim {

struct ExtractParams {
  enum class Mode {
    truth,  ///< keep the link's pixels by label (a perfect colour+depth segmentation) ...
    depth,  ///< no labels: depth range, crop box, then RANSAC removal of large planes
  };
  Mode mode = Mode::truth;
  /// truth: keep this fraction of non-link pixels within leakage_px of the link's
  /// silhouette (imperfect segmentation leaks background and occluder points in).
  double leakage = 0.0;
  int leakage_px = 2;  ///< [px], Chebyshev distance to the nearest link pixel
  double min_depth = 0.2;  ///< [m], both modes
  double max_depth = 1.5;  ///< [m], both modes
  std::optional<Eigen::AlignedBox3d> crop_C;  ///< depth: keep points in this box [m, C]
  int max_planes = 2;             ///< depth: planes removed at most (table, wall)
  double plane_threshold = 0.01;  ///< depth: inlier distance [m]
  double min_plane_fraction = 0.1;  ///< depth: a plane must hold this fraction of the points
  int ransac_iterations = 200;      ///< depth: hypotheses per plane

  void validate() const;  ///< throws std::invalid_argument naming the field
  /// "truth" or "depth"; throws std::invalid_argument otherwise.
  [[nodiscard]] static Mode mode_from(const std::string& name);
};

/// The cloud [m, C] of a rendered frame. Random choices (leakage, RANSAC) come from
/// (seed, frame) only.
[[nodiscard]] Cloud extract_cloud(const DepthFrame& frame, const io::Intrinsics& intrinsics,
                                  int component_count, const ExtractParams& params,
                                  std::uint64_t seed, std::uint64_t frame_index);

/// The planes step of the depth mode, usable on a real recording's cloud too: removes
/// up to params.max_planes planes that each hold at least min_plane_fraction of the
/// points. Deterministic for a given seed.
[[nodiscard]] Cloud remove_planes(const Cloud& cloud, const ExtractParams& params,
                                  std::uint64_t seed);

}  // namespace linksight::sim
