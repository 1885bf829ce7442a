// The two-scale noise structure fitted by simulation (issue 20): the recording's surfaces
// are cast once, and candidate noise models are applied to the casts and read with the
// same ruler as the camera's frames (depth_stats), so the fit sees exactly what a
// comparison with the camera (linksight fidelity --rerender) sees, shape, jitter and
// quantization included, which the window model of fit_noise only approximates.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "linksight/sim/depth_stats.hpp"
#include "linksight/sim/sensor_noise.hpp"
#include "surface_render.hpp"

namespace linksight::sim {

TargetMismatch target_mismatch(const DepthStats& real, const DepthStats& sim) {
  TargetMismatch m;
  const double band = std::log(1.25);
  char line[160];
  int sides = 0;  // of the edge statistics (TargetStatistic::sides), set below
  const auto add = [&](const std::string& name, double e, double r, double s, bool difference) {
    ++m.statistics;
    m.cost += e * e;
    const TargetStatistic& t = m.compared.emplace_back(TargetStatistic{name, r, s, difference, e, sides});
    if (e > 1) {
      if (difference)
        std::snprintf(line, sizeof line, "%s %+.3f (sim - real)", name.c_str(), t.value());
      else
        std::snprintf(line, sizeof line, "%s %.2f", name.c_str(), t.value());
      m.outside.emplace_back(line);
    }
  };
  const auto ratio = [&](const std::string& name, double r, double s) {
    if (!(r > 0)) return;
    add(name, std::abs(std::log(std::max(s, 1e-9) / r)) / band, r, s, false);
  };
  // A bin the camera fills and the simulation leaves (nearly) empty counts as a simulation
  // that reads nothing there, as far off as can be: a model must not lower its cost by
  // losing the windows that would measure it (a steeper incidence cut-off can).
  // kMinSimWindows, not kMinBinWindows: the simulation's count moves with its draws.
  const auto bins = [&](const std::vector<SigmaBin>& r, const std::vector<SigmaBin>& s,
                        const std::string& what, double unit) {
    for (std::size_t b = 0; b < r.size(); ++b) {
      if (r[b].windows < kMinBinWindows) continue;
      const bool seen = b < s.size() && s[b].windows >= kMinSimWindows;
      ratio(what + " " + std::to_string(static_cast<int>(std::lround(r[b].lo * unit))) + "-" +
                std::to_string(static_cast<int>(std::lround(r[b].hi * unit))),
            r[b].sigma, seen ? s[b].sigma : 0.0);
    }
  };
  bins(real.sigma_by_depth, sim.sigma_by_depth, "sigma z_cm", 100);
  bins(real.sigma_by_angle, sim.sigma_by_angle, "sigma deg", 180 / std::numbers::pi);
  bins(real.sigma_quad_by_angle, sim.sigma_quad_by_angle, "quadratic sigma deg",
       180 / std::numbers::pi);
  bins(real.sigma_quad_by_depth, sim.sigma_quad_by_depth, "quadratic sigma z_cm", 100);
  for (int l = 0; l < 4; ++l) {
    for (const bool rows : {true, false}) {
      const double r =
          (rows ? real.correlation_rows : real.correlation_cols)[static_cast<std::size_t>(l)];
      const double s =
          (rows ? sim.correlation_rows : sim.correlation_cols)[static_cast<std::size_t>(l)];
      const std::string name = std::string("correlation ") + (rows ? "rows" : "columns") + " lag " +
                               std::to_string(l + 1);
      if (std::abs(r) < kSmallCorrelation)
        add(name, std::abs(s - r) / kSmallCorrelationTol, r, s, true);
      else
        ratio(name, r, s);
    }
  }
  ratio("quadratic beats plane", real.quad_beats_plane, sim.quad_beats_plane);
  // The side away from the projector as the camera's frames decide it; the simulation's
  // own side where it decides one, else the same image side (a model whose bands no longer
  // decide a side is compared, not let off).
  if (real.projector_side != 0) {
    const int side = sim.projector_side != 0 ? sim.projector_side : real.projector_side;
    const EdgeSide& r = real.projector_side < 0 ? real.near_right : real.near_left;
    const EdgeSide& s = side < 0 ? sim.near_right : sim.near_left;
    sides = 3 * real.projector_side + side;
    ratio("other side invalid at 1 px", r.invalid_1px, s.invalid_1px);
    ratio("other side invalid at 2 px", r.invalid_2px, s.invalid_2px);
    ratio("other side band median px", r.band_median_px, s.band_median_px);
    sides = 0;
  }
  ratio("flying rate beside bands", real.flying_band_rate, sim.flying_band_rate);
  ratio("holes per frame", real.holes_per_frame, sim.holes_per_frame);
  return m;
}

std::vector<std::optional<LeftOut>> leave_groups_out(const std::vector<io::DepthImage>& real,
                                                     const std::vector<io::DepthImage>& sim,
                                                     const io::Intrinsics& intrinsics,
                                                     const DepthStatsParams& params,
                                                     int max_groups) {
  const std::size_t n = real.size();
  if (n < 3)
    throw std::invalid_argument("target_jackknife: " + std::to_string(n) +
                                " frames; leaving one out needs at least 3");
  if (max_groups < 2)
    throw std::invalid_argument("target_jackknife: max_groups = " + std::to_string(max_groups) +
                                ": must be >= 2");
  if (sim.empty() || sim.size() % n != 0)
    throw std::invalid_argument("target_jackknife: " + std::to_string(sim.size()) +
                                " simulated images are not draws of " + std::to_string(n) +
                                " frames");
  const std::size_t draws = sim.size() / n;
  // Consecutive frames in g groups (frame f in group f g / n): one frame each up to
  // max_groups, so that the cost stays that many readings of the recording.
  const std::size_t g = std::min(n, static_cast<std::size_t>(max_groups));
  const auto group = [&](std::size_t f) { return f * g / n; };
  std::vector<std::optional<LeftOut>> out(g);
  std::vector<io::DepthImage> r, s;
  for (std::size_t i = 0; i < g; ++i) {
    r.clear();
    s.clear();
    for (std::size_t f = 0; f < n; ++f)
      if (group(f) != i) r.push_back(real[f]);
    for (std::size_t d = 0; d < draws; ++d)
      for (std::size_t f = 0; f < n; ++f)
        if (group(f) != i) s.push_back(sim[d * n + f]);
    try {
      out[i] = LeftOut{depth_stats(r, intrinsics, params), depth_stats(s, intrinsics, params, &r)};
    } catch (const std::invalid_argument&) {
      // unreadable without this group: every statistic's se is NaN
    }
  }
  return out;
}

double jackknife_se(const std::vector<double>& left) {
  const std::size_t g = left.size();
  if (g < 2) return std::numeric_limits<double>::quiet_NaN();
  double mean = 0;
  for (const double v : left) mean += v;  // a NaN reading makes the se NaN
  mean /= static_cast<double>(g);
  double ss = 0;
  for (const double v : left) ss += (v - mean) * (v - mean);
  return std::sqrt(static_cast<double>(g - 1) / static_cast<double>(g) * ss);
}

std::vector<TargetSpread> target_jackknife(const DepthStats& real, const DepthStats& sim,
                                           const std::vector<std::optional<LeftOut>>& left) {
  std::vector<TargetSpread> out;
  for (const TargetStatistic& t : target_mismatch(real, sim).compared) out.push_back({t, 0.0});
  // Each statistic's value without each group, where it was compared as on all frames.
  std::vector<std::vector<double>> values(out.size(),
                                          std::vector<double>(left.size(), std::nan("")));
  for (std::size_t i = 0; i < left.size(); ++i) {
    if (!left[i]) continue;
    const TargetMismatch m = target_mismatch(left[i]->real, left[i]->sim);
    for (std::size_t k = 0; k < out.size(); ++k) {
      const TargetStatistic& a = out[k].all;
      for (const TargetStatistic& t : m.compared)
        if (t.name == a.name && t.difference == a.difference && t.sides == a.sides) {
          values[k][i] = t.value();
          break;
        }
    }
  }
  for (std::size_t k = 0; k < out.size(); ++k) out[k].se = jackknife_se(values[k]);
  return out;
}

std::vector<TargetSpread> target_jackknife(const std::vector<io::DepthImage>& real,
                                           const std::vector<io::DepthImage>& sim,
                                           const io::Intrinsics& intrinsics,
                                           const DepthStatsParams& params, int max_groups) {
  const std::vector<std::optional<LeftOut>> left =
      leave_groups_out(real, sim, intrinsics, params, max_groups);
  return target_jackknife(depth_stats(real, intrinsics, params),
                          depth_stats(sim, intrinsics, params, &real), left);
}

namespace {

// One frame's noise-free cast, owned (the sensor's last_noise_input only views it).
struct Cast {
  int width = 0, height = 0;
  std::vector<float> depth_m, incidence, cos_camera, cos_projector, reflectance;
  std::vector<std::uint8_t> lit;
  explicit Cast(const NoiseInput& in)
      : width(in.width),
        height(in.height),
        depth_m(in.depth_m.begin(), in.depth_m.end()),
        incidence(in.incidence.begin(), in.incidence.end()),
        cos_camera(in.cos_camera.begin(), in.cos_camera.end()),
        cos_projector(in.cos_projector.begin(), in.cos_projector.end()),
        reflectance(in.reflectance.begin(), in.reflectance.end()),
        lit(in.lit.begin(), in.lit.end()) {}
  [[nodiscard]] NoiseInput input() const {
    return {width, height, depth_m, incidence, cos_camera, cos_projector, reflectance, lit};
  }
};

// The searched parameters: a and c's scale and k_theta's over the one-field fit's, the
// pixel-scale widths along rows and columns [px], the low field's [px] and share,
// dropouts.max_incidence [deg], and the hole rate's scale over the one-field fit's (which
// counts every interior hole as a drawn one; the steeper incidence cut-off leaves holes of
// its own, most of them on what the rebuilt surfaces fill, which depth_stats' `seen`
// leaves out: docs/sensor.md, "Holes counted where the camera saw a surface"), the
// pixel-scale field's depth power (the quadratic-fit sigma by depth pins it: the camera's
// grows faster with depth than a + c z^2; docs/sensor.md, "The pixel-scale noise by
// depth"), and the angle term's power (the sigma by angle pins it: the camera's grows
// more slowly towards grazing incidence than Nguyen et al.'s square; docs/sensor.md, "The
// angle term's power").
constexpr int kParams = 11;
using Vec = std::array<double, kParams>;
constexpr Vec kStart = {4, 2, 2, 2, 8, 8, 0.95, 0, 1, 0, 2};  // max_incidence: the start's
constexpr Vec kStep = {1, 0.5, 0.4, 0.4, 2, 2, 0.02, 3, 0.1, 0.5, 0.25};
// The low field on a grid of 2 px (AxialNoise::low_stride_px): within the sensor's time
// budget (bench/README.md), and its widths kept to 3 strides or more.
constexpr int kLowStridePx = 2;
constexpr Vec kLo = {0.5, 0, 0.4, 0.4, 3 * kLowStridePx, 3 * kLowStridePx, 0, 40, 0, -2, 0.5};
constexpr Vec kHi = {20, 20, 8, 8, 20, 20, 0.998, 89, 2, 4, 4};

NoiseParams candidate(const NoiseParams& base, const Vec& x) {
  NoiseParams n = base;
  AxialNoise& ax = n.axial;
  ax.a = base.axial.a * x[0];
  ax.c = base.axial.c * x[0];
  // The angle term's scale is the one at 60 degrees (q = 2), so that a step of the power
  // turns the term about the middle of the camera's angles instead of scaling it.
  ax.k_theta = base.axial.k_theta * x[1] * std::pow(2.0, base.axial.angle_power - x[10]);
  ax.kernel = AxialKernel::gaussian;
  ax.correlation_px = x[2];
  ax.correlation_cols_px = x[3];
  ax.low_share = x[6];
  ax.low_rows_px = x[4];
  ax.low_cols_px = x[5];
  ax.low_angle_term = false;
  ax.low_stride_px = kLowStridePx;
  n.dropouts.max_incidence = x[7] * std::numbers::pi / 180;
  n.dropouts.hole_rate = base.dropouts.hole_rate * x[8];
  ax.pixel_depth_power = x[9];
  ax.angle_power = x[10];
  return n;
}

}  // namespace

void RerenderFitParams::validate() const {
  if (sweeps < 0)
    throw std::invalid_argument("sweeps = " + std::to_string(sweeps) + ": must be >= 0");
  if (draws < 1)
    throw std::invalid_argument("draws = " + std::to_string(draws) + ": must be >= 1");
  if (lateral_sigma_px) {
    // The model's own range (LateralNoise's fields), on a block that is valid but for it,
    // so that the error is the jitter's.
    NoiseParams jitter;
    jitter.lateral.sigma_px = *lateral_sigma_px;
    try {
      jitter.validate();
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(std::string("lateral_sigma_px: ") + e.what());
    }
  }
}

NoiseFit fit_noise_rerendered(const std::vector<io::DepthImage>& frames, const io::Intrinsics& K,
                              const DepthStats& stats, const DepthStats* shape,
                              const NoiseParams& start, const RerenderFitParams& params) {
  try {
    params.validate();
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("fit_noise_rerendered: ") + e.what());
  }
  NoiseFit fit = fit_noise(stats, start, shape, NoiseStructure::one_field);
  if (params.lateral_sigma_px) {  // switched on, so that the casts use what was given
    fit.params.lateral.enabled = true;
    fit.params.lateral.sigma_px = *params.lateral_sigma_px;
  }
  // The power is measured where the camera's frames hold windows (the bins the mismatch
  // reads), and held there beyond.
  bool measured = false;
  for (const SigmaBin& b : stats.sigma_quad_by_depth)
    if (b.windows >= kMinBinWindows) {
      AxialNoise& ax = fit.params.axial;
      if (!measured) ax.pixel_depth_min_m = b.lo;
      ax.pixel_depth_max_m = b.hi;
      measured = true;
    }
  const NoiseParams base = fit.params;
  // The search fits max_incidence, which the one-field fit keeps.
  for (std::string& note : fit.notes)
    if (note.rfind("lateral.sigma_px and dropouts.max_incidence", 0) == 0) {
      if (params.lateral_sigma_px) {
        char given[96];
        std::snprintf(given, sizeof given,
                      "lateral.sigma_px %g px as given, dropouts.min_signal kept: not measured",
                      base.lateral.sigma_px);
        note = given;
      } else {
        note = "lateral.sigma_px and dropouts.min_signal kept: not measured";
      }
    }
  // The casts depend on the lateral jitter and the projector only, which the search keeps.
  std::vector<Cast> casts;
  for (std::size_t f = 0; f < frames.size(); ++f) {
    const SurfaceRender r =
        render_surface(frames[f], K, base, params.seed, f, DepthSurfaceParams{});
    casts.emplace_back(r.sensor->last_noise_input(r.frame));
  }
  const CameraParams camera = surface_camera(K);
  // Draw-major, as rerender_surfaces returns its draws: the same images for the same model.
  const std::size_t n = casts.size();
  std::vector<io::DepthImage> images(n * static_cast<std::size_t>(params.draws));
  std::vector<float> depth_m;
  int evaluations = 0;
  const auto mismatch = [&](const Vec& x) {
    ++evaluations;
    try {
      SensorNoise noise(candidate(base, x), camera);
      for (std::size_t d = 0; d < static_cast<std::size_t>(params.draws); ++d)
        for (std::size_t f = 0; f < n; ++f) {
          const std::size_t k = draw_index(n, d, f);
          noise.apply(casts[f].input(), params.seed, k, params.threads, images[k], depth_m);
        }
      return target_mismatch(stats, depth_stats(images, K, {}, &frames));
    } catch (const std::invalid_argument&) {
      // Out of the model's ranges, or too few windows left: not a candidate.
      TargetMismatch none;
      none.cost = std::numeric_limits<double>::infinity();
      return none;
    }
  };
  Vec x = kStart;
  x[7] = base.dropouts.max_incidence * 180 / std::numbers::pi;
  for (int d = 0; d < kParams; ++d) x[d] = std::clamp(x[d], kLo[d], kHi[d]);
  TargetMismatch best = mismatch(x);
  const double start_cost = best.cost;
  // A pattern search: each parameter a step down and then up, every step that lowers the
  // cost taken at once (the next tries start from it, and a step down taken skips the step
  // up); a sweep without one halves the steps.
  Vec step = kStep;
  for (int sweep = 0; sweep < params.sweeps; ++sweep) {
    bool moved = false;
    for (int d = 0; d < kParams; ++d)
      for (const double sign : {-1.0, 1.0}) {
        Vec y = x;
        y[d] = std::clamp(y[d] + sign * step[d], kLo[d], kHi[d]);
        if (y[d] == x[d]) continue;
        if (TargetMismatch m = mismatch(y); m.cost < best.cost) {
          best = std::move(m), x = y, moved = true;
          break;  // a step up from here is the point just left, which cost more
        }
      }
    if (!moved)
      for (double& s : step) s /= 2;
  }
  fit.params = candidate(base, x);
  const AxialNoise& ax = fit.params.axial;
  char line[640];
  std::snprintf(
      line, sizeof line,
      "two-scale structure by re-rendering %zu frames, %d draw%s each (%d renders, %d "
      "sweeps): axial a, c "
      "x%.3g and k_theta x%.3g (at 60 deg) of the one-field fit's with the angle power %.3g, "
      "pixel-scale field %.2f x %.2f px "
      "with the angle term, low-frequency field %.2f x %.2f px with %.4f of a + c z^2, "
      "pixel-scale share x (z / %.2f m)^%.3g over %.2f-%.2f m, "
      "dropouts.max_incidence %.1f deg, hole rate x%.3g; target mismatch %.3g (start "
      "%.3g) over the issue-20 statistics",
      frames.size(), params.draws, params.draws == 1 ? "" : "s", evaluations, params.sweeps,
      x[0], x[1], x[10], ax.correlation_px, ax.correlation_cols_px, ax.low_rows_px, ax.low_cols_px,
      ax.low_share, ax.pixel_depth_ref_m, x[9], ax.pixel_depth_min_m, ax.pixel_depth_max_m, x[7],
      x[8], best.cost, start_cost);
  fit.notes.emplace_back(line);
  std::string out = "outside 0.8-1.25 on the fitted frames:";
  for (const std::string& o : best.outside) out += " " + o + ";";
  if (best.outside.empty()) out += " none";
  fit.notes.push_back(out);
  return fit;
}

}  // namespace linksight::sim
