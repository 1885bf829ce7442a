#include "linksight/sim/noise.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace linksight::sim {

AxialNoise::Point AxialNoise::point(double z, double theta) const {
  const double th = std::min(std::abs(theta), theta_cap);
  return {z, std::sqrt(std::max(z, 1e-6)), th / (std::numbers::pi / 2 - th)};
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

NoiseParams NoiseParams::sr300() { return NoiseParams{}; }

NoiseParams NoiseParams::preset(const std::string& name) {
  if (name == "off") return off();
  if (name == "sr300") return sr300();
  throw std::invalid_argument("noise preset '" + name + "': expected off or sr300");
}

namespace {
void check(bool ok, const char* field, double v, const char* rule) {
  if (!ok) throw std::invalid_argument(std::string("noise.") + field + " = " + std::to_string(v) +
                                       ": " + rule);
}
}  // namespace

void NoiseParams::validate() const {
  const double half_pi = std::numbers::pi / 2;
  check(axial.a >= 0 && std::isfinite(axial.a), "axial.a", axial.a, "must be >= 0");
  check(axial.c >= 0 && std::isfinite(axial.c), "axial.c", axial.c, "must be >= 0");
  check(axial.k_theta >= 0 && std::isfinite(axial.k_theta), "axial.k_theta", axial.k_theta,
        "must be >= 0");
  check(axial.correlation_px >= 0 && axial.correlation_px <= 10, "axial.correlation_px",
        axial.correlation_px, "must be in [0, 10] px");
  check(axial.theta_cap >= 0 && axial.theta_cap < half_pi, "axial.theta_cap", axial.theta_cap,
        "must be in [0, pi/2)");
  check(lateral.sigma_px >= 0 && lateral.sigma_px <= 10, "lateral.sigma_px", lateral.sigma_px,
        "must be in [0, 10]");
  check(std::isfinite(shadow.baseline) && std::abs(shadow.baseline) <= 1, "shadow.baseline",
        shadow.baseline, "must be in [-1, 1] m");
  check(dropouts.max_incidence > 0 && dropouts.max_incidence <= half_pi,
        "dropouts.max_incidence", dropouts.max_incidence, "must be in (0, pi/2]");
  check(dropouts.min_signal >= 0 && std::isfinite(dropouts.min_signal), "dropouts.min_signal",
        dropouts.min_signal, "must be >= 0");
  check(dropouts.hole_rate >= 0 && dropouts.hole_rate <= 1e4, "dropouts.hole_rate",
        dropouts.hole_rate, "must be in [0, 10000]");
  check(dropouts.hole_median_px >= 1 && dropouts.hole_median_px <= Dropouts::kMaxHolePx,
        "dropouts.hole_median_px", dropouts.hole_median_px, "must be in [1, 1000] px");
  check(dropouts.hole_p90_px >= dropouts.hole_median_px && dropouts.hole_p90_px <= Dropouts::kMaxHolePx,
        "dropouts.hole_p90_px", dropouts.hole_p90_px, "must be in [hole_median_px, 1000] px");
  check(edges.jump > 0 && std::isfinite(edges.jump), "edges.jump", edges.jump, "must be > 0");
  check(edges.p_drop >= 0 && edges.p_drop <= 1, "edges.p_drop", edges.p_drop, "must be in [0, 1]");
  check(edges.band_p1 >= 0 && edges.band_p1 <= 1, "edges.band_p1", edges.band_p1, "must be in [0, 1]");
  check(edges.band_p2 >= 0 && edges.band_p2 <= 1, "edges.band_p2", edges.band_p2, "must be in [0, 1]");
  check(edges.flying_position >= 0 && edges.flying_position <= 1, "edges.flying_position",
        edges.flying_position, "must be in [0, 1]");
  check(edges.flying_spread >= 0 && edges.flying_spread <= 1, "edges.flying_spread",
        edges.flying_spread, "must be in [0, 1]");
  check(edges.p_flying >= 0 && edges.p_flying <= 1, "edges.p_flying", edges.p_flying,
        "must be in [0, 1]");
}

}  // namespace linksight::sim
