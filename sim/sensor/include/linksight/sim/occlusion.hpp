#pragma once
/// @file A generated occluder that hides a set fraction of the link: the scene key
/// `occlusion`, which makes "occluded fraction" a sweepable number instead of a box
/// placed by hand for every camera pose.

#include "linksight/sim/camera.hpp"
#include "linksight/sim/sensor.hpp"
#include "linksight/sim/trajectory.hpp"
#include "linksight/tracker/fields.hpp"

#include <string_view>

namespace linksight::sim {

/// A thin box held between the camera and the link over [from_s, to_s). It is sized on
/// the straight rest pose of the link at from_s so that, seen from the camera, it covers
/// `fraction` of the link's length at its middle or at its tip end; the truth occluded
/// fraction a frame reports is what it really hides.
enum class OcclusionSite { middle, tip };
/// "middle" / "tip"; parse throws std::invalid_argument naming the value and choices.
[[nodiscard]] std::string_view to_string(OcclusionSite site);
[[nodiscard]] OcclusionSite parse_occlusion_site(std::string_view name);

struct ScreenOcclusion {
  using Where = OcclusionSite;
  double fraction = 0.0;  ///< of the link's length seen from the camera, [0, 1); 0: none
  Where at = Where::middle;
  double from_s = 1.0;    ///< appears [s]
  double to_s = 2.0;      ///< disappears [s]
  double gap = 0.05;      ///< from the link's axis toward the camera [m]; >= r + 7 mm
  double height = 0.10;   ///< across the link, as seen at the link's distance [m]
  /// Carried with the base, so the hidden part stays the same while the link moves
  /// (sampled at every camera frame); else it stays where it appeared.
  bool follow_base = true;
  /// The keys of the scene's `occlusion` block (fields.hpp).
  template <class Archive>
  void fields(Archive& ar) {
    ar("fraction", fraction, fields::in(0, 0.95));
    ar("at", at, parse_occlusion_site);
    ar("from_s", from_s, fields::in(0, 1e6));
    ar("to_s", to_s, fields::in(0, 1e6));  // and > from_s
    ar("gap_m", gap, fields::in(1e-3, 0.5));
    ar("height_m", height, fields::in(1e-3, 0.5));
    ar("follow_base", follow_base);
  }
  void validate() const;  ///< throws fields::FieldError naming the key
};

/// The occluder of `o` for a chain whose base follows `base`, seen by `camera`, over
/// `duration_s`. Throws fields::FieldError naming the key: fraction not > 0, a gap
/// that does not clear the balls (gap_m >= ball radius + 7 mm), from_s not before
/// duration_s, or the link at from_s not in front of the camera beyond the gap.
[[nodiscard]] Occluder screen_occluder(const ScreenOcclusion& o, const ComponentGeometry& chain,
                                       const BaseTrajectory& base, const CameraParams& camera,
                                       double duration_s);

}  // namespace linksight::sim
