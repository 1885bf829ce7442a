#pragma once
/// @file From a depth frame to the tracker's cloud: the paper's preprocessing
/// (Sec. IV.C). Deprojection goes through io::depth_to_cloud, the code that reads real
/// depth PNGs, so a simulated frame and a real one become clouds the same way.

#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "linksight/io/depth_png.hpp"
#include "linksight/io/intrinsics.hpp"
#include "linksight/sim/sensor.hpp"
#include "linksight/tracker/cloud.hpp"
#include "linksight/tracker/fields.hpp"

namespace linksight::sim {

enum class ExtractMode {
  truth,  ///< keep the link's pixels by label (a perfect colour+depth segmentation) ...
  depth,  ///< no labels: depth range, crop box, then RANSAC removal of large planes
};
/// "truth" / "depth"; parse throws std::invalid_argument naming the value and choices.
[[nodiscard]] std::string_view to_string(ExtractMode mode);
[[nodiscard]] ExtractMode parse_extract_mode(std::string_view name);

struct ExtractParams {
  using Mode = ExtractMode;
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
  /// depth: and be wider than this both ways: its inliers must occupy 7 x 7 cells of a
  /// fifth of it on a grid in the plane, along their principal axes or turned by 30 or 60
  /// degrees (any square 1.5 times as wide and any disc 1.7 times as wide passes) [m].
  /// A row of the link's balls seen from the front lies within plane_threshold of a plane
  /// for much of its 30 mm width and can hold min_plane_fraction once the table drops out
  /// of view; a table or a wall passes, the row (straight or bent, alone or with a small
  /// object in the same plane) does not. A refused plane stays in the cloud and the search
  /// goes on without it, so up to 1 / min_plane_fraction planes are tried. 0: any plane.
  double min_plane_width = 0.1;
  int ransac_iterations = 200;      ///< depth: hypotheses per plane

  /// The keys of the scene's `segmentation` block (fields.hpp); crop_min_m and
  /// crop_max_m there are read as a pair into crop_C, not fields.
  template <class Archive>
  void fields(Archive& ar) {
    ar("mode", mode, parse_extract_mode);
    ar("leakage", leakage, fields::in(0, 1));
    ar("leakage_px", leakage_px, fields::in(0, 50));
    ar("min_depth_m", min_depth, fields::in(0, 100));
    ar("max_depth_m", max_depth, fields::in(0, 100));  // and > min_depth_m
    ar("max_planes", max_planes, fields::in(0, 10));
    ar("plane_threshold_m", plane_threshold, fields::in(1e-5, 1));
    ar("min_plane_fraction", min_plane_fraction, fields::in(1e-3, 1));
    ar("min_plane_width_m", min_plane_width, fields::in(0, 100));
    ar("ransac_iterations", ransac_iterations, fields::in(1, 100000));
  }
  void validate() const;  ///< throws fields::FieldError naming the key
};

/// The cloud [m, C] of a rendered frame. Random choices (leakage, RANSAC) come from
/// (seed, frame) only.
[[nodiscard]] Cloud extract_cloud(const DepthFrame& frame, const io::Intrinsics& intrinsics,
                                  int component_count, const ExtractParams& params,
                                  std::uint64_t seed, std::uint64_t frame_index);

/// The planes step of the depth mode, usable on a real recording's cloud too: removes
/// up to params.max_planes planes that each hold at least min_plane_fraction of the
/// points and are wider than min_plane_width (passing over narrower ones). Deterministic
/// for a given seed.
[[nodiscard]] Cloud remove_planes(const Cloud& cloud, const ExtractParams& params,
                                  std::uint64_t seed);

}  // namespace linksight::sim
