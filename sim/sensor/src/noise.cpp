#include "linksight/sim/noise.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "linksight/io/echo.hpp"

namespace linksight::sim {

std::string_view to_string(AxialKernel kernel) {
  return kernel == AxialKernel::matern52 ? "matern52" : "gaussian";
}

AxialKernel parse_axial_kernel(std::string_view name) {
  if (name == "gaussian") return AxialKernel::gaussian;
  if (name == "matern52") return AxialKernel::matern52;
  throw std::invalid_argument("axial kernel '" + std::string(name) + "': expected gaussian or matern52");
}

AxialNoise::Point AxialNoise::point(double z, double theta) const {
  const double th = std::min(std::abs(theta), theta_cap);
  const double q = th / (std::numbers::pi / 2 - th);
  // For the power 2 sigma() multiplies by q twice, as before the power existed.
  return {z, std::sqrt(std::max(z, 1e-6)), q, angle_power == 2 ? q * q : std::pow(q, angle_power)};
}

double AxialNoise::sigma(double z, double theta) const { return sigma(point(z, theta)); }

NoiseParams NoiseParams::off() {
  NoiseParams p;
  p.axial.enabled = false;
  p.lateral.enabled = false;
  p.shadow.enabled = false;
  p.dropouts.enabled = false;
  p.edges.enabled = false;
  p.quantize = false;
  return p;
}

NoiseParams NoiseParams::sr300() {
  // `linksight calibrate-noise --input tests/data/sr305-hand/frames --intrinsics
  // tests/data/sr305-hand/intrinsics.json --structure two-scale` (docs/sensor.md, "The
  // sr300 preset"), rounded to the digits the fit resolves; the terms it leaves out
  // (lateral jitter, min_signal, theta_cap, hole sizes) as in the one-field preset.
  NoiseParams p;
  p.axial.a = 0.00014;         // 0.140 mm
  p.axial.c = 0.0027;          // 2.70 mm/m^2
  p.axial.k_theta = 0.00075;  // m^1.5
  // The camera's sigma grows more slowly towards grazing incidence than the square
  // (docs/sensor.md, "The angle term's power").
  p.axial.angle_power = 1.5625;
  p.axial.correlation_px = 2.4;
  p.axial.correlation_cols_px = 2.8;
  p.axial.low_share = 0.97;
  p.axial.low_rows_px = 6.5;
  p.axial.low_cols_px = 8;
  p.axial.low_angle_term = false;
  p.axial.low_stride_px = 2;
  // The pixel-scale field's share of a + c z^2 scaled by (z / 0.65 m)^3.25, over the depths
  // the frames hold windows at (docs/sensor.md, "The pixel-scale noise by depth").
  p.axial.pixel_depth_power = 3.25;
  p.axial.pixel_depth_ref_m = 0.65;
  p.axial.pixel_depth_min_m = 0.5;
  p.axial.pixel_depth_max_m = 0.9;
  p.dropouts.max_incidence = 72 * (std::numbers::pi / 180.0);  // as a scene reads 72
  // 51.5 while re-rendered holes were counted where the camera saw no surface too
  // (docs/sensor.md, "Holes counted where the camera saw a surface").
  p.dropouts.hole_rate = 78.9;
  p.edges.drop_steps = true;
  return p;
}

NoiseParams NoiseParams::sr300_one_field() { return NoiseParams{}; }

std::vector<std::string> NoiseParams::preset_names() { return {"off", "sr300", "sr300-one-field"}; }

NoiseParams NoiseParams::preset(const std::string& name) {
  if (name == "off") return off();
  if (name == "sr300") return sr300();
  if (name == "sr300-one-field") return sr300_one_field();
  const std::vector<std::string> names = preset_names();
  std::string expected;
  for (std::size_t k = 0; k < names.size(); ++k)
    expected += (k == 0 ? "" : k + 1 == names.size() ? " or " : ", ") + names[k];
  throw std::invalid_argument("noise preset '" + io::echo(name) + "': expected " + expected);
}

void NoiseParams::validate() const {
  fields::check(*this, "noise");
  if (!(dropouts.hole_p90_px >= dropouts.hole_median_px))
    fields::fail("noise", "dropouts.hole_p90_px", dropouts.hole_p90_px,
                 "must be >= hole_median_px (" + format_shortest(dropouts.hole_median_px) + ")");
  if (axial.kernel == AxialKernel::matern52)
    for (const auto& [key, r] : {std::pair{"axial.correlation_px", axial.correlation_px},
                                 std::pair{"axial.correlation_cols_px", axial.correlation_cols_px}})
      if (r > 0 && r < kMinMaternRangePx)
        fields::fail("noise", key, r,
                     "must be 0 or >= " + format_shortest(kMinMaternRangePx) +
                         " with kernel matern52 (its filter follows the covariance from there)");
  if (axial.low_share > 0 && axial.low_stride_px > 1)
    for (const auto& [key, w] : {std::pair{"axial.low_rows_px", axial.low_rows_px},
                                 std::pair{"axial.low_cols_px", axial.low_cols_px}})
      if (w < 2 * axial.low_stride_px)
        fields::fail("noise", key, w,
                     "must be >= 2 x low_stride_px (" + std::to_string(axial.low_stride_px) +
                         "): a coarser grid shows in the field");
  if (axial.pixel_depth_power < 0 && !(axial.pixel_depth_min_m > 0))
    fields::fail("noise", "axial.pixel_depth_min_m", axial.pixel_depth_min_m,
                 "must be > 0 with a negative pixel_depth_power (" +
                     format_shortest(axial.pixel_depth_power) + "): the factor would be infinite at 0");
  if (!(axial.pixel_depth_max_m > axial.pixel_depth_min_m))
    fields::fail("noise", "axial.pixel_depth_max_m", axial.pixel_depth_max_m,
                 "must be > pixel_depth_min_m (" + format_shortest(axial.pixel_depth_min_m) + ")");
  if (axial.correlation_cols_px > 0 && !(axial.correlation_px > 0))
    fields::fail("noise", "axial.correlation_cols_px", axial.correlation_cols_px,
                 "needs correlation_px > 0 (a white pixel-scale term has no width)");
}

}  // namespace linksight::sim
