#pragma once
/// @file The depth camera's noise and artefact model. Every term can be switched off;
/// `NoiseParams::off()` is an ideal depth camera, `NoiseParams::sr300()` the default: the
/// two-scale model (issue 20) fitted by `linksight calibrate-noise --structure two-scale`
/// to the 11 SR305 frames in tests/data/sr305-hand. The in-class defaults below are the
/// `sr300-one-field` preset, the one-field model `calibrate-noise` fitted to the same
/// frames before (issue 8), kept so that scenes can reproduce their numbers
/// (docs/sensor.md, "The sr300 preset", says where each value comes from); values marked
/// "estimate" are not measured.

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <string_view>
#include <vector>

#include "linksight/tracker/fields.hpp"

namespace linksight::sim {

/// The shape of the pixel-scale axial field's correlation (AxialNoise::kernel).
/// - `gaussian`: white noise blurred by a Gaussian of standard deviation w [px];
///   neighbours at lag L correlate by exp(-L^2 / (4 w^2)).
/// - `matern52`: a Matern-5/2 covariance of range r [px],
///   (1 + sqrt(5) L / r + 5 L^2 / (3 r^2)) exp(-sqrt(5) L / r), r >= 3 px: smooth like the
///   Gaussian near 0 but with a longer tail, which the window estimators read closer to
///   the real SR305 frames' row correlations (docs/sensor.md; not the preset).
enum class AxialKernel { gaussian, matern52 };
/// The shortest Matern range [px]: from here the sensor's sampled filter gives the
/// covariance within 0.005 at every lag (at 1 px it is 0.1 off), so what the window model
/// predicts is what the sensor draws.
inline constexpr double kMinMaternRangePx = 3.0;
/// "gaussian" / "matern52"; parse throws std::invalid_argument naming the value and choices.
[[nodiscard]] std::string_view to_string(AxialKernel kernel);
[[nodiscard]] AxialKernel parse_axial_kernel(std::string_view name);

/// Axial (along the optical axis) Gaussian noise:
/// sigma_z(z, theta) = a + c z^2 + k_theta / sqrt(z) * (theta / (pi/2 - theta))^angle_power,
/// the form of Nguyen, Izadi & Lovell (3DIMPVT 2012, Eq. 5; their power is 2) with their
/// constant terms replaced by a + c z^2. theta is the incidence angle at the camera.
struct AxialNoise {
  bool enabled = true;
  double a = 0.000048;   ///< [m] (fitted: 0.048 mm)
  double c = 0.0009;     ///< [1/m] (fitted: 0.9 mm/m^2)
  double k_theta = 0.00032;  ///< [m^1.5] (fitted; Nguyen et al. have 0.0001 for the Kinect)
  /// The angle term is evaluated at min(theta, theta_cap) so it stays finite [rad].
  double theta_cap = 80.0 * std::numbers::pi / 180.0;
  /// The angle term's power of theta / (pi/2 - theta): 2 is Nguyen et al.'s; below 2 it
  /// grows more slowly towards grazing incidence (issue 20: the SR305's plane-fit sigma
  /// grows 1.7x and 1.8x from 30-45 to 45-60 to 60-75 deg, where q^2 grows 3.8x and 4.6x
  /// between the bins' middles; docs/sensor.md, "The angle term's power").
  double angle_power = 2;
  /// Spatial correlation: the unit normal field is a white field blurred by a Gaussian of
  /// this standard deviation [px] and rescaled to unit variance, so neighbours at lag L
  /// correlate by exp(-L^2 / (4 s^2)); with `kernel` matern52, filtered to a Matern-5/2
  /// covariance of this range [px]. 0: white (every pixel its own draw).
  double correlation_px = 1.6;  ///< (fitted: the camera filters its depth)
  /// The same width along columns (v) where it differs from the rows' (u) [px]; 0: the
  /// same as correlation_px (isotropic).
  double correlation_cols_px = 0;
  /// What correlation_px and correlation_cols_px are the widths of: `gaussian` (above, the
  /// preset's) or `matern52` (their Matern-5/2 ranges, at least 3 px, where the filter
  /// follows the covariance within 0.005; AxialKernel).
  AxialKernel kernel = AxialKernel::gaussian;
  /// A second, low-frequency term (issue 20): a unit field of its own, blurred by a
  /// Gaussian of low_rows_px along rows and low_cols_px along columns, takes this share of
  /// the axial variance sigma_z^2 and the pixel-scale term above the rest. 0: off, the
  /// one-field model (the images are then what they were before the term existed).
  double low_share = 0;
  double low_rows_px = 6;  ///< [px]
  double low_cols_px = 6;  ///< [px]
  /// Whether the low-frequency term takes its share of the whole sigma_z (true, as the term
  /// was first made) or of a + c z^2 only (false): then sigma_low = sqrt(low_share) (a + c
  /// z^2) and the pixel-scale field carries the angle term t in quadrature, sqrt((1 -
  /// low_share) (a + c z^2)^2 + t^2), so the noise gets rougher towards grazing incidence as
  /// the camera's does (issue 20). The pixel's sigma is then sqrt((a + c z^2)^2 + t^2), not
  /// sigma() (= a + c z^2 + t); the same at normal incidence either way.
  bool low_angle_term = true;
  /// The low-frequency field drawn on a grid of this many pixels and interpolated
  /// bilinearly (1: at every pixel, as the term was first made). A stride of 2 costs a
  /// quarter of the draws and about an eighth of the blur. Between grid nodes the variance
  /// dips: at a cell's centre to 0.97 of 1 for widths of 3 strides, 0.94 for 2 (the least
  /// accepted); the correlation stays within 0.01 of the Gaussian's from 3 strides.
  int low_stride_px = 1;
  /// With the low field apart from the angle term (low_share > 0, low_angle_term false):
  /// the pixel-scale field's share of a + c z^2 is scaled by r^p, r = z' / pixel_depth_ref_m
  /// with z' the depth held to [pixel_depth_min_m, pixel_depth_max_m], so that it can grow
  /// with depth faster than the low field, as the camera's does (docs/sensor.md, "The
  /// pixel-scale noise by depth"). The pixel's sigma is then sqrt((1 - low_share) ((a +
  /// c z^2) r^p)^2 + t^2) in the pixel-scale field and sqrt(low_share) (a + c z^2) in the
  /// low one. The range is where the power was measured: a power law is not extrapolated.
  /// Without the two fields apart (low_share 0 or low_angle_term true) it does nothing, as
  /// the low field's widths do without a low field. 0: as before the term existed.
  double pixel_depth_power = 0;
  double pixel_depth_ref_m = 0.65;  ///< [m] the depth the power is relative to
  double pixel_depth_min_m = 0;     ///< [m] nearer, the factor is the one at this depth (> 0 for a power < 0)
  double pixel_depth_max_m = 10;    ///< [m] farther, the one at this depth; > pixel_depth_min_m
  /// r^pixel_depth_power (above): what the pixel-scale field's share of a + c z^2 is scaled
  /// by at depth z [m]; 1 when the power is 0.
  [[nodiscard]] double pixel_depth_factor(double z) const {
    if (pixel_depth_power == 0) return 1.0;
    return std::pow(std::clamp(z, pixel_depth_min_m, pixel_depth_max_m) / pixel_depth_ref_m,
                    pixel_depth_power);
  }
  /// The pixel-scale term's widths along rows and columns [px] (0: white).
  [[nodiscard]] double rows_px() const { return correlation_px; }
  [[nodiscard]] double cols_px() const {
    return correlation_px > 0 && correlation_cols_px > 0 ? correlation_cols_px : correlation_px;
  }
  /// sigma_z [m] at depth z [m] and incidence theta [rad]: sigma(point(z, theta)).
  [[nodiscard]] double sigma(double z, double theta) const;
  /// What sigma needs of a point, apart from a, c and k_theta: so that a fit can try many
  /// coefficients on the same points with this one formula (q_power ties a point to the
  /// angle_power it was made with).
  struct Point {
    double z = 0;       ///< depth [m]
    double root_z = 0;  ///< sqrt(max(z, 1e-6)) [m^0.5]
    double q = 0;       ///< theta' / (pi/2 - theta'), theta' = min(|theta|, theta_cap)
    double q_power = 0;  ///< q^angle_power
  };
  [[nodiscard]] Point point(double z, double theta) const;
  [[nodiscard]] double sigma(const Point& p) const {
    // The power 2 rounds as before the power existed, ((k_theta / root_z) q) q.
    if (angle_power == 2) return base(p) + k_theta / p.root_z * p.q * p.q;
    return base(p) + k_theta / p.root_z * p.q_power;
  }
  /// sigma without its angle term, a + c z^2 [m]: what the low-frequency field scales when
  /// low_angle_term is false.
  [[nodiscard]] double base(const Point& p) const { return a + c * p.z * p.z; }
  /// The keys of the scene's `noise.axial` block (fields.hpp).
  template <class Archive>
  void fields(Archive& ar) {
    ar("enabled", enabled);
    ar("a_m", a, fields::in(0, 0.1));
    ar("c_per_m", c, fields::in(0, 0.1));
    ar("k_theta", k_theta, fields::in(0, 0.1));
    ar("theta_cap_deg", theta_cap, fields::deg(fields::in(0, 89.9)));
    ar("angle_power", angle_power, fields::in(0.5, 4));
    ar("correlation_px", correlation_px, fields::in(0, 20));
    ar("correlation_cols_px", correlation_cols_px, fields::in(0, 20));
    ar("kernel", kernel, parse_axial_kernel);
    ar("low_share", low_share, fields::in(0, 0.999));
    ar("low_rows_px", low_rows_px, fields::in(0.5, 20));
    ar("low_cols_px", low_cols_px, fields::in(0.5, 20));
    ar("low_angle_term", low_angle_term);
    ar("low_stride_px", low_stride_px, fields::in(1, 8));
    ar("pixel_depth_power", pixel_depth_power, fields::in(-4, 4));
    ar("pixel_depth_ref_m", pixel_depth_ref_m, fields::in(0.1, 10));
    ar("pixel_depth_min_m", pixel_depth_min_m, fields::in(0, 10));  // and > 0 for a power < 0
    ar("pixel_depth_max_m", pixel_depth_max_m, fields::in(0.01, 10));  // and > pixel_depth_min_m
  }
};

/// Sub-pixel jitter of each ray: its pixel coordinates get N(0, sigma_px^2) each.
struct LateralNoise {
  bool enabled = true;
  /// [px] (estimate, bounded by the data: with 0.5 px the residual correlation at 1 px
  /// falls to 0.7, the real frames read 0.83)
  double sigma_px = 0.1;
  template <class Archive>
  void fields(Archive& ar) {
    ar("enabled", enabled);
    ar("sigma_px", sigma_px, fields::in(0, 10));
  }
};

/// The projector of a structured-light camera sits at `baseline` along the camera's +x
/// axis; a surface point it cannot light has no depth.
struct ProjectorShadow {
  bool enabled = true;
  /// [m], signed (negative: projector on the camera's -x side; fitted: the shadows fall
  /// on the image-right of foreground objects, 63 mm)
  double baseline = -0.063;
  template <class Archive>
  void fields(Archive& ar) {
    ar("enabled", enabled);
    ar("baseline_m", baseline, fields::in(-1, 1));
  }
};

/// Pixels the camera cannot decode.
struct Dropouts {
  bool enabled = true;
  /// Incidence at the camera or at the projector above this loses the pixel [rad].
  double max_incidence = 75.0 * std::numbers::pi / 180.0;
  /// Low-signal proxy: reflectance * cos(theta_p) / z^2 [1/m^2] below this loses the
  /// pixel. 0.1 keeps a reflectance-1 surface to 1.5 m up to about 76 degrees (estimate).
  double min_signal = 0.1;
  /// Random holes: on average `hole_rate` per frame (Poisson), each a 4-connected blob
  /// grown from a uniformly placed pixel to an area drawn log-normal with this median and
  /// 90th percentile, rounded, in [1, kMaxHolePx] px.
  double hole_rate = 64.0;      ///< (fitted: 12.4 seen per frame on 19% valid pixels)
  double hole_median_px = 2.0;  ///< [px] of area (fitted)
  double hole_p90_px = 19.0;    ///< [px] of area, >= hole_median_px (fitted)
  static constexpr int kMaxHolePx = 1000;
  template <class Archive>
  void fields(Archive& ar) {
    ar("enabled", enabled);
    ar("max_incidence_deg", max_incidence, fields::deg(fields::in(0.1, 90)));
    ar("min_signal", min_signal, fields::in(0, 1e6));
    ar("hole_rate", hole_rate, fields::in(0, 1e4));
    ar("hole_median_px", hole_median_px, fields::in(1, kMaxHolePx));
    ar("hole_p90_px", hole_p90_px, fields::in(1, kMaxHolePx));  // and >= hole_median_px
  }
};

/// Depth discontinuities, where two 4-neighbours' noise-free depths differ by more than
/// `jump`. On the far side, the invalid band a coded-light camera leaves: the pixel next
/// to the near surface is dropped with probability band_p1, the one after it (2 px from
/// the near surface, along a row or column) with band_p2. On the near side (and next to a
/// pixel that sees nothing) the edge pixel is dropped with p_drop, else it becomes a
/// flying pixel with p_flying: z_near + u (z_far - z_near), u uniform in
/// [flying_position - flying_spread, flying_position + flying_spread] within [0, 1].
/// With drop_steps, last, a reported pixel with a reported 4-neighbour more than `jump`
/// nearer is dropped: the camera never reports two such neighbours (docs/sensor.md).
struct EdgeEffects {
  bool enabled = true;
  double jump = 0.02;              ///< [m]
  double band_p1 = 0.69;           ///< (fitted, given p_drop)
  double band_p2 = 0.96;           ///< (fitted, given p_drop)
  double p_drop = 0.5;             ///< (estimate: not separable from band_p1, band_p2)
  double p_flying = 0.10;          ///< (fitted, given p_drop)
  double flying_position = 0.42;   ///< mean of u (fitted)
  double flying_spread = 0.46;     ///< half-width of u's range (fitted)
  bool drop_steps = false;         ///< no two reported neighbours more than `jump` apart
  template <class Archive>
  void fields(Archive& ar) {
    ar("enabled", enabled);
    ar("jump_m", jump, fields::in(1e-6, 10));
    ar("band_p1", band_p1, fields::in(0, 1));
    ar("band_p2", band_p2, fields::in(0, 1));
    ar("p_drop", p_drop, fields::in(0, 1));
    ar("p_flying", p_flying, fields::in(0, 1));
    ar("flying_position", flying_position, fields::in(0, 1));
    ar("flying_spread", flying_spread, fields::in(0, 1));
    ar("drop_steps", drop_steps);
  }
};

struct NoiseParams {
  AxialNoise axial;
  LateralNoise lateral;
  ProjectorShadow shadow;
  Dropouts dropouts;
  EdgeEffects edges;
  bool quantize = true;  ///< round depth to the depth unit (SR300: 1/8 mm)

  /// Every term off: the ideal camera (depth still in range and quantized to the unit
  /// only when `quantize`; off() leaves quantization off too).
  [[nodiscard]] static NoiseParams off();
  /// The two-scale preset (issue 20): the defaults above with the all-frames fit of
  /// `calibrate-noise --structure two-scale` (noise.cpp lists its values).
  [[nodiscard]] static NoiseParams sr300();
  /// The defaults above: the one-field model (issue 8), `sr300` until issue 20.
  [[nodiscard]] static NoiseParams sr300_one_field();
  /// One of preset_names(); throws std::invalid_argument naming the preset otherwise.
  [[nodiscard]] static NoiseParams preset(const std::string& name);
  /// "off", "sr300", "sr300-one-field".
  [[nodiscard]] static std::vector<std::string> preset_names();
  /// The keys of the scene's `noise` block; `preset` and `scale` there are read, not
  /// fields: a preset is where the block starts, a scale multiplies the random terms.
  template <class Archive>
  void fields(Archive& ar) {
    ar("axial", axial);
    ar("lateral", lateral);
    ar("shadow", shadow);
    ar("dropouts", dropouts);
    ar("edges", edges);
    ar("quantize", quantize);
  }
  /// Throws fields::FieldError naming the key ("noise.axial.a_m = ...").
  void validate() const;
};

}  // namespace linksight::sim
