// linksight calibrate-noise: measures a depth camera's noise and artefacts on a real
// recording (16-bit depth PNGs of any static or slowly moving scene) and fits the
// simulated SR300's noise model to them. Prints a report, writes the `noise:` block a
// scene file accepts as it is, and (with --report) the statistics as JSON.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

#include "cli_common.hpp"
#include "commands.hpp"
#include "format.hpp"
#include "linksight/io/atomic_file.hpp"
#include "linksight/io/error.hpp"
#include "linksight/io/frames.hpp"
#include "linksight/sim/depth_stats.hpp"
#include "linksight/sim/scene.hpp"
#include "linksight/tracker/quantile.hpp"

namespace linksight::cli {
namespace fs = std::filesystem;
namespace {

struct CalibrateOptions {
  std::string input, intrinsics, out, report;
  bool quiet = false;
  bool no_shape_correction = false;
  bool no_figures = false;
  std::string structure = "one-field";  // sim::NoiseStructure
  std::string half = "all";             // sim::FrameHalf
  int sweeps = sim::RerenderFitParams{}.sweeps;  // two-scale's search
  bool sweeps_given = false;
  int draws = sim::RerenderFitParams{}.draws;  // two-scale: noise draws per frame, pooled
  bool draws_given = false;
  double lateral_sigma_px = 0;  // two-scale: the casts' jitter, when given
  bool lateral_given = false;
  std::uint64_t seed = sim::RerenderFitParams{}.seed;  // two-scale: the re-renders' draws
  bool seed_given = false;
};

// The --structure values, from the structures' one list.
std::vector<std::string> structure_names() {
  std::vector<std::string> names;
  for (const sim::NoiseStructure s : sim::kNoiseStructures) names.emplace_back(sim::to_string(s));
  return names;
}

// What was fitted: the frames, and the options that chose the fit where they are not the
// defaults. The block's first line and the report's, so that either says how to make it
// again (the fit's notes follow it in the block, and close the report).
std::string fit_source_line(const std::string& source, int frames, const std::string& half,
                            std::uint64_t seed) {
  std::ostringstream h;
  h << "# linksight calibrate-noise: fitted to " << frames << " frames of " << source;
  std::vector<std::string> chosen;
  if (half != "all") chosen.push_back("--half " + half);
  if (seed != sim::RerenderFitParams{}.seed) chosen.push_back("--seed " + std::to_string(seed));
  for (std::size_t i = 0; i < chosen.size(); ++i)
    h << (i == 0 ? " (" : ", ") << chosen[i] << (i + 1 == chosen.size() ? ")" : "");
  h << "\n";
  return h.str();
}

std::string noise_yaml(const sim::NoiseFit& fit, const std::string& source_line) {
  std::string y = source_line;
  for (const std::string& note : fit.notes) y += "# note: " + note + "\n";
  fit.params.validate();  // a fit outside the model's ranges would write a block no scene loads
  return y + sim::noise_yaml(fit.params);  // every term in full: reads back the same
}

nlohmann::json stats_json(const sim::DepthStats& s) {
  auto bins = [](const std::vector<sim::SigmaBin>& v, double unit) {
    nlohmann::json a = nlohmann::json::array();
    for (const auto& b : v)
      a.push_back({{"lo", b.lo * unit}, {"hi", b.hi * unit}, {"windows", b.windows},
                   {"sigma_mm", b.sigma * 1e3}, {"centre", b.centre * unit}});
    return a;
  };
  auto scales = [](const std::vector<sim::DepthStats::Scale>& v) {
    nlohmann::json a = nlohmann::json::array();
    for (const auto& sc : v)
      a.push_back({{"window_px", sc.window}, {"windows", sc.windows},
                   {"plane_sigma_mm", sc.sigma * 1e3}, {"quadratic_sigma_mm", sc.sigma_quad * 1e3},
                   {"quadratic_beats_plane", sc.quad_beats_plane}});
    return a;
  };
  auto side = [](const sim::EdgeSide& e) {
    return nlohmann::json{{"edges", e.edges},
                          {"direct_jumps", e.direct},
                          {"invalid_at_1px", e.invalid_1px},
                          {"invalid_at_2px", e.invalid_2px},
                          {"band_median_px", e.band_median_px},
                          {"fit_slope_mm", e.slope * 1e3},
                          {"fit_intercept_px", e.intercept},
                          {"fit_r", e.fit_r}};
  };
  return {{"frames", s.frames},
          {"valid_px", s.valid_px},
          {"depth_step_mm", s.depth_step * 1e3},
          {"windows", s.windows},
          {"sigma_by_depth_m", bins(s.sigma_by_depth, 1.0)},
          {"sigma_by_angle_deg", bins(s.sigma_by_angle, kDegPerRad)},
          {"residual_correlation_lag_1_to_4_px", s.correlation},
          {"residual_correlation_rows_lag_1_to_6_px", s.correlation_rows},
          {"residual_correlation_columns_lag_1_to_6_px", s.correlation_cols},
          {"quadratic_sigma_by_angle_deg", bins(s.sigma_quad_by_angle, kDegPerRad)},
          {"quadratic_sigma_by_depth_m", bins(s.sigma_quad_by_depth, 1.0)},
          {"quadratic_beats_plane", s.quad_beats_plane},
          {"sigma_by_window", scales(s.scales)},
          {"neighbour_pairs", s.neighbour_pairs},
          {"neighbour_jumps", s.neighbour_jumps},
          {"edges_near_left", side(s.near_left)},
          {"edges_near_right", side(s.near_right)},
          {"projector_side", s.projector_side},
          {"baseline_mm", s.baseline * 1e3},
          {"flying_rate", s.flying_rate},
          {"flying_band_rate", s.flying_band_rate},
          {"band_side_pixels", s.band_side_pixels},
          {"band_side_flying", s.band_side_flying},
          {"flying_position", s.flying_position},
          {"flying_position_iqr", s.flying_iqr},
          {"flying_per_discontinuity", s.flying_per_edge},
          {"valid_fraction", s.pixels > 0 ? static_cast<double>(s.valid_px) / s.pixels : 0.0},
          {"holes_per_frame", s.holes_per_frame},
          {"hole_sizes_px", s.hole_sizes}};
}

// Bin k of sigma by depth (or by angle): what the surfaces' shape reads there (0 when not
// measured), and the fitted model as the plane fit reads it (its correlation lowers the
// reading; its median over the bin's own windows) with that shape added in quadrature [m].
std::pair<double, double> model_read(const sim::DepthStats& s, const sim::NoiseFit& fit,
                                     const sim::DepthStats* shape, bool by_depth, std::size_t k) {
  const sim::AxialReading read(fit.params.axial, s.window);
  const sim::SigmaBin& b = (by_depth ? s.sigma_by_depth : s.sigma_by_angle)[k];
  double q = 0;
  if (shape != nullptr) {
    const auto& sb = by_depth ? shape->sigma_by_depth : shape->sigma_by_angle;
    if (k < sb.size() && sb[k].windows >= 10) q = sb[k].sigma;
  }
  std::vector<double> model;
  for (const auto& w : s.samples)
    if (sim::in_sigma_bin(w, b, by_depth, s.depth_bin_max_angle))
      model.push_back(read.sigma(w.z, w.angle));
  const double m = model.empty() ? 0.0 : quantile(model, 0.5);
  return {q, std::sqrt(m * m + q * q)};
}

// The recording and the fitted model (with the shape) as tools/plot_fidelity.py draws them.
nlohmann::json figure_series(const sim::DepthStats& s, const sim::NoiseFit& fit,
                             const sim::DepthStats* shape) {
  nlohmann::json model;
  for (const bool by_depth : {true, false}) {
    const auto& v = by_depth ? s.sigma_by_depth : s.sigma_by_angle;
    nlohmann::json a = nlohmann::json::array();
    for (std::size_t k = 0; k < v.size(); ++k) {
      if (v[k].windows == 0) continue;
      a.push_back({{"centre", v[k].centre * (by_depth ? 1.0 : kDegPerRad)},
                   {"sigma_mm", model_read(s, fit, shape, by_depth, k).second * 1e3}});
    }
    model[by_depth ? "sigma_by_depth" : "sigma_by_angle"] = a;
  }
  return {{"series", {{"recording", stats_series(s)}, {"fitted model + surface shape", model}}}};
}

void print_report(std::ostream& os, const std::string& source_line, const sim::DepthStats& s,
                  const sim::NoiseFit& fit, const sim::DepthStats* shape) {
  os << source_line << std::fixed;
  os << s.frames << " frames, " << s.valid_px << " valid pixels, " << s.windows
     << " flat 15x15 windows; depth step " << std::setprecision(3) << s.depth_step * 1e3
     << " mm\n\nplane-fit sigma by depth (incidence < 30 deg); shape: the same on the frames' "
        "surfaces re-rendered without noise; the fitted model at each bin's windows, shape added:\n";
  auto bins = [&](const std::vector<sim::SigmaBin>& v, double unit, const char* what) {
    const bool by_depth = unit == 1.0;
    for (std::size_t k = 0; k < v.size(); ++k) {
      const sim::SigmaBin& b = v[k];
      if (b.windows == 0) continue;
      const auto [q, both] = model_read(s, fit, shape, by_depth, k);
      os << "  " << what << " [" << std::setprecision(unit > 1 ? 0 : 2) << b.lo * unit << ", "
         << b.hi * unit << ")  windows " << std::setw(5) << b.windows << "  sigma_mm "
         << std::setprecision(2) << b.sigma * 1e3 << "  shape_mm " << q * 1e3
         << "  model_and_shape_mm " << both * 1e3 << "\n";
    }
  };
  bins(s.sigma_by_depth, 1.0, "z_m");
  os << "plane-fit sigma by incidence (all depths):\n";
  bins(s.sigma_by_angle, kDegPerRad, "deg");
  os << std::setprecision(2) << "residual correlation at 1..4 px: " << s.correlation[0] << " "
     << s.correlation[1] << " " << s.correlation[2] << " " << s.correlation[3] << "\n";
  os << "  along rows at 1..6 px:   ";
  for (const double c : s.correlation_rows) os << " " << c;
  os << "\n  along columns at 1..6 px:";
  for (const double c : s.correlation_cols) os << " " << c;
  os << "\nquadratic-fit sigma by incidence (all depths):\n";
  for (const sim::SigmaBin& b : s.sigma_quad_by_angle)
    if (b.windows > 0)
      os << "  deg [" << std::setprecision(0) << b.lo * kDegPerRad << ", " << b.hi * kDegPerRad
         << ")  windows " << std::setw(5) << b.windows << "  sigma_mm " << std::setprecision(2)
         << b.sigma * 1e3 << "\n";
  os << "quadratic-fit sigma by depth (incidence under " << std::setprecision(0)
     << s.depth_bin_max_angle * kDegPerRad << " deg):\n";
  for (const sim::SigmaBin& b : s.sigma_quad_by_depth)
    if (b.windows > 0)
      os << "  z_m [" << std::setprecision(2) << b.lo << ", " << b.hi << ")  windows "
         << std::setw(5) << b.windows << "  sigma_mm " << b.sigma * 1e3 << "\n";
  os << "windows where a quadratic's sigma is below " << sim::kQuadBeatsPlane
     << " x the plane's: " << std::setprecision(0) << 100 * s.quad_beats_plane << "%\n";
  for (const auto& sc : s.scales)
    os << "  " << sc.window << "x" << sc.window << " px: " << sc.windows
       << " windows, median sigma_mm plane " << std::setprecision(2) << sc.sigma * 1e3
       << ", quadratic " << sc.sigma_quad * 1e3 << ", quadratic below " << sim::kQuadBeatsPlane
       << " x plane in " << std::setprecision(0) << 100 * sc.quad_beats_plane << "%\n";
  os << "valid neighbours (rows and columns) more than 20 mm apart: " << s.neighbour_jumps
     << " of " << s.neighbour_pairs << " pairs (" << std::setprecision(1)
     << (s.neighbour_pairs ? 1e6 * static_cast<double>(s.neighbour_jumps) / static_cast<double>(s.neighbour_pairs) : 0.0)
     << " per million)\n\n"
     << std::setprecision(2);  // what the lines below were written with
  auto side = [&](const char* name, const sim::EdgeSide& e) {
    os << "  " << name << ": " << e.edges << " edges, " << e.direct << " direct jumps, "
       << "first/second pixel past the near surface invalid " << 100 * e.invalid_1px << "% / "
       << 100 * e.invalid_2px << "%, median band " << std::setprecision(1) << e.band_median_px
       << " px, width = " << e.slope * 1e3 << " mm x f(1/z1 - 1/z2) + " << e.intercept
       << " px (r " << std::setprecision(2) << e.fit_r << ")\n";
  };
  os << "depth discontinuities > 20 mm, scanning rows:\n";
  side("near surface left of the gap ", s.near_left);
  side("near surface right of the gap", s.near_right);
  os << std::setprecision(1) << "projector: "
     << (s.projector_side < 0   ? "image-left"
         : s.projector_side > 0 ? "image-right"
                                : "undecided")
     << ", baseline " << s.baseline * 1e3 << " mm\n"
     << "flying pixels: " << 100 * s.flying_rate << "% of the valid pixels next to a band ("
     << 100 * s.flying_band_rate << "% of those within 2 px of an invalid run), at "
     << std::setprecision(2) << s.flying_position << " (IQR " << s.flying_iqr
     << ") of the way from near to far, " << std::setprecision(3) << s.flying_per_edge
     << " of the discontinuities hold a lone one\n";
  os << std::setprecision(1) << "interior holes: " << s.holes_per_frame << " per frame";
  if (!s.hole_sizes.empty())  // as fit_noise reads them
    os << ", median " << std::lround(quantile(s.hole_sizes, 0.5)) << " px, p90 "
       << std::lround(quantile(s.hole_sizes, 0.9)) << " px";
  os << "\n\nnotes:\n";
  for (const std::string& n : fit.notes) os << "  " << n << "\n";
}

int run_calibrate(const CalibrateOptions& o) {
  // Options that do not apply are refused before any frame is read.
  const sim::NoiseStructure structure = sim::parse_noise_structure(o.structure);
  if (o.sweeps_given && structure != sim::NoiseStructure::two_scale)
    throw io::InputError("--sweeps: only the two-scale structure searches (--structure " +
                         o.structure + ")");
  if (o.draws_given && structure != sim::NoiseStructure::two_scale)
    throw io::InputError("--draws: only the two-scale structure re-renders (--structure " +
                         o.structure + ")");
  if (o.lateral_given && structure != sim::NoiseStructure::two_scale)
    throw io::InputError("--lateral-sigma-px: only the two-scale structure casts the frames "
                         "(--structure " + o.structure + ")");
  if (o.seed_given && structure != sim::NoiseStructure::two_scale)
    throw io::InputError("--seed: only the two-scale structure draws noise (--structure " +
                         o.structure + ")");
  sim::RerenderFitParams rerender;
  rerender.sweeps = o.sweeps;
  rerender.draws = o.draws;
  rerender.seed = o.seed;
  if (o.lateral_given) rerender.lateral_sigma_px = o.lateral_sigma_px;
  try {  // the search's own checks (the jitter's range is LateralNoise's), before any frame is read
    rerender.validate();
  } catch (const std::invalid_argument& e) {
    // CLI11 holds --sweeps and --draws to their ranges, so what is left is the jitter's:
    // named as the option the user typed.
    std::string what = e.what();
    const std::string field = "lateral_sigma_px: ";
    if (what.rfind(field, 0) == 0) what = "--lateral-sigma-px: " + what.substr(field.size());
    throw io::InputError(what);
  }
  const io::Intrinsics K = io::read_intrinsics(o.intrinsics);
  const std::vector<io::DepthImage> frames =
      take_half(read_depth_frames(o.input, K, o.intrinsics, "calibrate-noise"), K, o.half,
                o.input);
  sim::DepthStats stats;
  try {
    stats = sim::depth_stats(frames, K);
  } catch (const std::invalid_argument& e) {
    throw io::InputError(o.input + ": " + e.what());
  }
  // What the surfaces' own shape puts into the plane fit: the recording's geometry
  // re-rendered without noise (quantization kept).
  sim::DepthStats shape;
  if (!o.no_shape_correction) {
    sim::NoiseParams quiet = sim::NoiseParams::off();
    quiet.quantize = true;
    try {
      shape = sim::depth_stats(sim::rerender_surfaces(frames, K, quiet, 1), K);
    } catch (const std::invalid_argument& e) {
      throw io::InputError(o.input + ": re-rendering its surfaces: " + e.what());
    }
  }
  const sim::DepthStats* shape_p = o.no_shape_correction ? nullptr : &shape;
  sim::NoiseFit fit;
  if (structure == sim::NoiseStructure::two_scale) {
    try {
      fit = sim::fit_noise_rerendered(frames, K, stats, shape_p,
                                      sim::NoiseParams::sr300_one_field(), rerender);
    } catch (const std::invalid_argument& e) {
      throw io::InputError(o.input + ": re-rendering its surfaces: " + e.what());
    }
  } else {
    fit = sim::fit_noise(stats, sim::NoiseParams::sr300_one_field(), shape_p, structure);
  }
  io::StagedFiles out;
  const std::string source_line = fit_source_line(o.input, stats.frames, o.half, o.seed);
  out.open(o.out) << noise_yaml(fit, source_line);
  if (!o.report.empty()) {
    std::error_code ec;
    fs::create_directories(o.report, ec);
    if (ec) throw io::InputError(o.report + ": cannot create report directory: " + ec.message());
    std::ostringstream text;
    print_report(text, source_line, stats, fit, shape_p);
    out.open(fs::path(o.report) / "report.txt") << text.str();
    out.open(fs::path(o.report) / "stats.json") << stats_json(stats).dump(2) << "\n";
    out.open(fs::path(o.report) / "calibration.json")
        << figure_series(stats, fit, shape_p).dump(1) << "\n";
  }
  out.commit();
  // Figures last, each written whole by the script; a failed plot is a warning.
  std::string warn;
  if (!o.report.empty() && !o.no_figures)
    warn = run_plot_script(
        script_path("LINKSIGHT_FIDELITY_PLOT_SCRIPT", LINKSIGHT_FIDELITY_PLOT_SCRIPT), o.report,
        o.quiet);
  if (!warn.empty()) std::cerr << "linksight calibrate-noise: " << io::printable_line(warn) << "\n";
  if (!o.quiet) {
    print_report(std::cout, source_line, stats, fit, shape_p);
    std::cout << "\nwrote " << o.out << " (a noise: block for a scene file)";
    if (!o.report.empty())
      std::cout << ", " << o.report << "/report.txt, stats.json, calibration.json, figures/";
    std::cout << "\n";
  }
  return kExitOk;
}

}  // namespace

Runner add_calibrate_noise(CLI::App& app) {
  auto o = std::make_shared<CalibrateOptions>();
  app.add_option("--input", o->input, "directory of 16-bit depth PNGs (a real recording)")
      ->required();
  app.add_option("--intrinsics", o->intrinsics, "intrinsics.json of the camera")->required();
  app.add_option("--out", o->out, "the fitted noise: block (YAML)")->required();
  app.add_option("--report", o->report, "directory for report.txt and stats.json");
  app.add_flag("--no-shape-correction", o->no_shape_correction,
               "fit sigma as measured, without subtracting what the surfaces' own shape puts "
               "into the plane fit (estimated by re-rendering them without noise)");
  app.add_option(
         "--structure", o->structure,
         "the axial field fitted: one-field (one isotropic width, the sr300-one-field preset's) "
         "or two-term (a pixel-scale and a low-frequency field, each with row and "
         "column widths) or matern52 (one Matern-5/2 field with row and column ranges) "
         "or two-scale (a pixel-scale field with the angle term and a low-frequency "
         "one without, fitted by re-rendering the frames: minutes; docs/sensor.md)")
      ->check(CLI::IsMember(structure_names()))
      ->capture_default_str();
  CLI::Option* sweeps =
      app.add_option("--sweeps", o->sweeps,
                     "two-scale: pattern-search sweeps (each re-renders the frames up to 20 times)")
          ->check(CLI::Range(0, 1000))
          ->capture_default_str();
  CLI::Option* draws = add_draws_option(app, o->draws, "two-scale: every candidate of the search");
  CLI::Option* lateral =
      app.add_option("--lateral-sigma-px", o->lateral_sigma_px,
                     "two-scale: the lateral jitter [px] the frames are cast with and the block "
                     "keeps (default: the sr300-one-field preset's estimate; not searched)");
  CLI::Option* seed = add_seed_option(
      app, o->seed,
      "two-scale: the seed of the re-renders' noise draws (another seed shows how far the fit "
      "moves with the draws alone)");
  add_half_option(app, o->half, "the frames fitted");
  app.add_flag("--no-figures", o->no_figures, "--report without the PNG figures");
  app.add_flag("--quiet", o->quiet, "print nothing on success");
  return [o, sweeps, draws, lateral, seed] {
    o->sweeps_given = sweeps->count() > 0;
    o->draws_given = draws->count() > 0;
    o->lateral_given = lateral->count() > 0;
    o->seed_given = seed->count() > 0;
    return run_calibrate(*o);
  };
}

}  // namespace linksight::cli
