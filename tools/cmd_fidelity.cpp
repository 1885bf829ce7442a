// linksight fidelity: the statistics calibrate-noise measures, on a real recording and on
// a simulated one (`linksight render`), side by side with their ratios, and figures that
// overlay them. How far a simulation is from its camera, in the camera's own numbers.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#include "cli_common.hpp"
#include "commands.hpp"
#include "format.hpp"
#include "linksight/io/atomic_file.hpp"
#include "linksight/io/error.hpp"
#include "linksight/io/frames.hpp"
#include "linksight/sim/depth_stats.hpp"
#include "linksight/tracker/quantile.hpp"
#include "linksight/sim/scene.hpp"

namespace linksight::cli {
namespace fs = std::filesystem;
namespace {

struct FidelityOptions {
  std::string real, sim, out;
  std::string real_intrinsics, sim_intrinsics;
  bool rerender = false;
  std::string noise_scene;  // --rerender: the noise block of this scene (default: sr300)
  bool no_figures = false, quiet = false, force = false;
  std::string half = "all";  // sim::FrameHalf of --real (and so of what --rerender renders)
  int draws = sim::RerenderFitParams{}.draws;  // --rerender: noise draws per frame, pooled
  bool draws_given = false;
};

// A recording: DIR/depth (as `linksight render` writes), DIR/frames or DIR itself; the
// intrinsics beside the frames' folder unless given. `half`: of its frames (take_half).
// With `rerender`, `images` are its own surfaces through the simulated camera instead,
// `draws` of each frame, draw-major: same geometry, so what differs is the sensor model.
struct Measured {
  io::Intrinsics K;
  std::vector<io::DepthImage> images;
  sim::DepthStats stats;
};
Measured measure(const std::string& dir, const std::string& intrinsics, const char* role,
                 const std::string& half, const sim::NoiseParams* rerender = nullptr,
                 int draws = 1) {
  try {
    fs::path frames = dir, k = intrinsics;
    std::error_code ec;
    for (const char* sub : {"depth", "frames"}) {
      if (fs::is_directory(fs::path(dir) / sub, ec)) {
        frames = fs::path(dir) / sub;
        break;
      }
    }
    if (k.empty()) k = fs::path(dir) / "intrinsics.json";
    Measured m;
    m.K = io::read_intrinsics(k);
    m.images =
        take_half(read_depth_frames(frames.string(), m.K, k.string(), "fidelity"), m.K, half, dir);
    try {
      if (rerender != nullptr) {
        // The re-render fills the camera's bands and gaps, and holes the model cuts there
        // have no counterpart in the camera's frame (depth_stats' `seen`).
        const std::vector<io::DepthImage> seen = std::move(m.images);
        m.images = sim::rerender_surfaces(seen, m.K, *rerender, sim::kCompareSeed, draws);
        m.stats = sim::depth_stats(m.images, m.K, {}, &seen);
      } else {
        m.stats = sim::depth_stats(m.images, m.K);
      }
      return m;
    } catch (const std::invalid_argument& e) {
      throw io::InputError(dir + ": " + e.what());
    }
  } catch (const io::InputError& e) {
    throw io::InputError(std::string("--") + role + ": " + e.what());
  }
}

struct Row {
  std::string name;
  double real, sim;
};

// A bin (of sigma or of correlation) is a row where both sides read this many windows.
constexpr int kMinRowWindows = 5;

std::vector<Row> rows(const sim::DepthStats& r, const sim::DepthStats& s) {
  std::vector<Row> out;
  auto bins = [&](const std::vector<sim::SigmaBin>& a, const std::vector<sim::SigmaBin>& b,
                  const std::string& what, double unit, int digits) {
    for (std::size_t i = 0; i < a.size() && i < b.size(); ++i) {
      if (a[i].windows < kMinRowWindows || b[i].windows < kMinRowWindows) continue;
      std::ostringstream n;
      n << std::fixed << std::setprecision(digits) << "sigma_mm " << what << " " << a[i].lo * unit
        << "-" << a[i].hi * unit;
      out.push_back({n.str(), a[i].sigma * 1e3, b[i].sigma * 1e3});
    }
  };
  bins(r.sigma_by_depth, s.sigma_by_depth, "z_m", 1.0, 2);
  bins(r.sigma_by_angle, s.sigma_by_angle, "deg", kDegPerRad, 0);
  out.push_back({"correlation lag 1 px", r.correlation[0], s.correlation[0]});
  out.push_back({"correlation lag 2 px", r.correlation[1], s.correlation[1]});
  bins(r.sigma_quad_by_angle, s.sigma_quad_by_angle, "quadratic deg", kDegPerRad, 0);
  bins(r.sigma_quad_by_depth, s.sigma_quad_by_depth, "quadratic z_m", 1.0, 2);
  for (int l = 0; l < sim::kCorrelationLags; ++l) {
    const std::string lag = std::to_string(l + 1);
    out.push_back({"correlation rows lag " + lag + " px", r.correlation_rows[l], s.correlation_rows[l]});
    out.push_back({"correlation columns lag " + lag + " px", r.correlation_cols[l], s.correlation_cols[l]});
  }
  // The same by the windows' depth, at the lags 1-4.
  for (std::size_t b = 0; b < r.correlation_by_depth.size() && b < s.correlation_by_depth.size();
       ++b) {
    const sim::DepthStats::CorrelationBin &a = r.correlation_by_depth[b],
                                          &c = s.correlation_by_depth[b];
    if (a.windows < kMinRowWindows || c.windows < kMinRowWindows) continue;
    std::ostringstream z;
    z << std::fixed << std::setprecision(2) << " px z_m " << a.lo << "-" << a.hi;
    for (int l = 0; l < 4; ++l) {
      const std::string lag = std::to_string(l + 1);
      out.push_back({"correlation rows lag " + lag + z.str(), a.rows[l], c.rows[l]});
      out.push_back({"correlation columns lag " + lag + z.str(), a.cols[l], c.cols[l]});
    }
  }
  out.push_back({"quadratic beats plane share", r.quad_beats_plane, s.quad_beats_plane});
  for (std::size_t k = 0; k < r.scales.size() && k < s.scales.size(); ++k) {
    const std::string w = std::to_string(r.scales[k].window) + " px";
    out.push_back({"sigma_mm plane, window " + w, r.scales[k].sigma * 1e3, s.scales[k].sigma * 1e3});
    out.push_back({"sigma_mm quadratic, window " + w, r.scales[k].sigma_quad * 1e3,
                   s.scales[k].sigma_quad * 1e3});
    out.push_back({"quadratic beats plane, window " + w, r.scales[k].quad_beats_plane,
                   s.scales[k].quad_beats_plane});
  }
  const auto per_million = [](const sim::DepthStats& d) {
    return d.neighbour_pairs ? 1e6 * static_cast<double>(d.neighbour_jumps) /
                                   static_cast<double>(d.neighbour_pairs)
                             : 0.0;
  };
  out.push_back({"neighbour jumps > 20 mm per million", per_million(r), per_million(s)});
  auto side = [&](const sim::EdgeSide& a, const sim::EdgeSide& b, const std::string& which) {
    out.push_back({which + " invalid at 1 px", a.invalid_1px, b.invalid_1px});
    out.push_back({which + " invalid at 2 px", a.invalid_2px, b.invalid_2px});
    out.push_back({which + " direct jumps per edge", a.edges ? double(a.direct) / a.edges : 0,
                   b.edges ? double(b.direct) / b.edges : 0});
    out.push_back({which + " band median px", a.band_median_px, b.band_median_px});
  };
  // Compared as shadow side and other side: a simulation with its projector on the other
  // side is compared like for like, and the side itself is a row. With a side undecided
  // in either, by image side instead.
  if (r.projector_side != 0 && s.projector_side != 0) {
    const bool r_left = r.projector_side < 0, s_left = s.projector_side < 0;
    side(r_left ? r.near_left : r.near_right, s_left ? s.near_left : s.near_right, "shadow side");
    side(r_left ? r.near_right : r.near_left, s_left ? s.near_right : s.near_left, "other side");
  } else {
    side(r.near_left, s.near_left, "near surface left");
    side(r.near_right, s.near_right, "near surface right");
  }
  out.push_back({"projector side (-1 left, +1 right)", double(r.projector_side), double(s.projector_side)});
  out.push_back({"baseline_mm", r.baseline * 1e3, s.baseline * 1e3});
  out.push_back({"flying rate", r.flying_rate, s.flying_rate});
  out.push_back({"flying rate beside bands", r.flying_band_rate, s.flying_band_rate});
  out.push_back({"flying position", r.flying_position, s.flying_position});
  out.push_back({"holes per frame", r.holes_per_frame, s.holes_per_frame});
  // 0 px where no hole was seen, as the other statistics read 0 when not measured.
  const auto hole_px = [](const std::vector<int>& v, double q) { return v.empty() ? 0.0 : quantile(v, q); };
  out.push_back({"hole size median px", hole_px(r.hole_sizes, 0.5), hole_px(s.hole_sizes, 0.5)});
  out.push_back({"hole size p90 px", hole_px(r.hole_sizes, 0.9), hole_px(s.hole_sizes, 0.9)});
  out.push_back({"depth step mm", r.depth_step * 1e3, s.depth_step * 1e3});
  return out;
}

int run_fidelity(const FidelityOptions& o) {
  if (o.rerender == !o.sim.empty())
    throw io::InputError("fidelity: give either --sim DIR or --rerender");
  if (!o.noise_scene.empty() && !o.rerender)
    throw io::InputError("--noise-scene: only --rerender renders with it (a --sim recording has "
                         "its own noise)");
  if (o.draws_given && !o.rerender)
    throw io::InputError("--draws: only --rerender draws the noise (a --sim recording is read as it is)");
  io::StagedDir out(o.out, o.force);  // refuses an existing --out before any work
  const Measured real_m = measure(o.real, o.real_intrinsics, "real", o.half);
  sim::NoiseParams noise = sim::NoiseParams::sr300();
  if (!o.noise_scene.empty()) noise = sim::load_scene(o.noise_scene).noise;
  const Measured sim_m =
      o.rerender ? measure(o.real, o.real_intrinsics, "rerender", o.half, &noise, o.draws)
                 : measure(o.sim, o.sim_intrinsics, "sim", "all");
  const sim::DepthStats& real = real_m.stats;
  const sim::DepthStats& simulated = sim_m.stats;
  const std::vector<Row> table = rows(real, simulated);
  // The spread over the frames: only where each simulated image is a draw of one real
  // frame (--rerender), so that a frame can leave both sides.
  const std::size_t n_frames = real_m.images.size();
  const bool spread_read = o.rerender && n_frames >= 3;
  const std::vector<std::optional<sim::LeftOut>> left =
      spread_read ? sim::leave_groups_out(real_m.images, sim_m.images, real_m.K)
                  : std::vector<std::optional<sim::LeftOut>>{};
  // Each row's jackknife se of the camera's value and of sim - real (paired), from the
  // same readings as the targets' (NaN where a row is not read without a group).
  std::vector<std::vector<Row>> left_rows(left.size());
  for (std::size_t i = 0; i < left.size(); ++i)
    if (left[i]) left_rows[i] = rows(left[i]->real, left[i]->sim);
  const auto row_se = [&](const std::string& name, bool of_difference) {
    std::vector<double> values(left.size(), std::nan(""));
    for (std::size_t i = 0; i < left.size(); ++i)
      for (const Row& r : left_rows[i])
        if (r.name == name) values[i] = of_difference ? r.sim - r.real : r.real;
    return sim::jackknife_se(values);
  };
  std::ostringstream text;
  text << std::left << std::setw(44) << "statistic" << std::right << std::setw(10) << "real"
       << std::setw(10) << "sim" << std::setw(10) << "sim/real";
  if (spread_read)
    text << std::setw(10) << "se real" << std::setw(10) << "sim-real" << std::setw(10) << "se";
  text << "\n";
  nlohmann::json j_rows = nlohmann::json::array();
  for (const Row& r : table) {
    const double ratio = r.real != 0 ? r.sim / r.real : std::nan("");
    text << std::left << std::setw(44) << r.name << std::right << std::fixed << std::setprecision(3)
         << std::setw(10) << r.real << std::setw(10) << r.sim << std::setw(10) << ratio;
    nlohmann::json row = {{"statistic", r.name},
                          {"real", json_number(r.real)},
                          {"sim", json_number(r.sim)},
                          {"ratio", json_number(ratio)}};
    if (spread_read) {
      const double se_real = row_se(r.name, false), se_difference = row_se(r.name, true);
      text << std::setw(10) << se_real << std::setw(10) << r.sim - r.real << std::setw(10)
           << se_difference;
      row["se_real"] = json_number(se_real);
      row["difference"] = json_number(r.sim - r.real);
      row["se_difference"] = json_number(se_difference);
    }
    text << "\n";
    j_rows.push_back(row);
  }
  if (o.rerender)
    text << "(re-rendered holes count where the real frame shows a surface: docs/sensor.md, "
            "Holes)\n";
  if (spread_read)
    text << "(se real, se: the jackknife's over the frames, as the targets' below, of the "
            "camera's value and of sim - real)\n";
  // The targets with their spread over the frames.
  nlohmann::json j_targets = nullptr;
  if (o.rerender && n_frames < 3) {
    text << "\ntargets (issue 20): not listed: " << n_frames
         << " frames, and their spread needs 3 or more\n";
  } else if (o.rerender) {
    const std::vector<sim::TargetSpread> spread = sim::target_jackknife(real, simulated, left);
    text << "\ntargets (issue 20): sim/real, or sim - real for a correlation the camera reads\n"
         << "under " << std::defaultfloat << sim::kSmallCorrelation
         << "; se: jackknife over " << n_frames << " frames, "
         << std::min<std::size_t>(n_frames, sim::kJackknifeGroups)
         << " groups left out in turn (nan: not compared without one of them)\n"
         << std::left << std::setw(44) << "target" << std::right << std::setw(10) << "compared"
         << std::setw(10) << "value" << std::setw(10) << "se" << std::setw(10) << "band" << "\n";
    j_targets = nlohmann::json::array();
    for (const sim::TargetSpread& t : spread) {
      const char* kind = t.all.difference ? "sim-real" : "sim/real";
      const bool outside = t.all.e > 1;
      text << std::left << std::setw(44) << t.all.name << std::right << std::setw(10) << kind
           << std::fixed << std::setprecision(3) << std::setw(10) << t.all.value() << std::setw(10)
           << t.se << std::setw(10) << (outside ? "outside" : "inside") << "\n";
      j_targets.push_back({{"target", t.all.name}, {"compared", kind},
                           {"value", json_number(t.all.value())}, {"se", json_number(t.se)},
                           {"outside", outside}});
    }
  }
  io::write_file_atomic(out.path() / "fidelity.txt", [&](std::ostream& f) { f << text.str(); });
  // draws: how many noise draws of each frame the re-rendered side pools (1 for a --sim
  // recording, read as it is).
  const nlohmann::json j = {{"real", o.real}, {"half", o.half},
                            {"sim", o.rerender ? "rerender" : o.sim},
                            {"draws", o.rerender ? o.draws : 1}, {"rows", j_rows},
                            {"targets", j_targets},
                            {"series", {{"real", stats_series(real)}, {"sim", stats_series(simulated)}}}};
  io::write_file_atomic(out.path() / "fidelity.json", [&](std::ostream& f) { f << j.dump(1) << "\n"; });
  // Figures into the staging directory, so the output appears whole; a failed plot is a
  // warning, the tables stand.
  std::string warn;
  if (!o.no_figures)
    warn = run_plot_script(
        script_path("LINKSIGHT_FIDELITY_PLOT_SCRIPT", LINKSIGHT_FIDELITY_PLOT_SCRIPT), out.path(),
        o.quiet);
  out.commit();
  if (!o.quiet) std::cout << text.str();
  if (!warn.empty()) std::cerr << "linksight fidelity: " << io::printable_line(warn) << "\n";
  if (!o.quiet) std::cout << "wrote " << o.out << "/fidelity.txt, fidelity.json"
                          << (o.no_figures ? "" : ", figures/") << "\n";
  return kExitOk;
}

}  // namespace

Runner add_fidelity(CLI::App& app) {
  auto o = std::make_shared<FidelityOptions>();
  app.add_option("--real", o->real, "real recording: depth PNGs in DIR, DIR/frames or DIR/depth")
      ->required();
  app.add_option("--sim", o->sim, "simulated recording (linksight render --out DIR)");
  app.add_flag("--rerender", o->rerender,
               "instead of --sim: the real recording's own surfaces (rebuilt from its depth, "
               "noise smoothed away) rendered through the simulated camera");
  app.add_option("--noise-scene", o->noise_scene,
                 "--rerender: use this scene file's noise block (default: the sr300 preset)");
  app.add_option("--real-intrinsics", o->real_intrinsics, "default: DIR/intrinsics.json");
  app.add_option("--sim-intrinsics", o->sim_intrinsics, "default: DIR/intrinsics.json");
  app.add_option("--out", o->out, "output directory (fidelity.txt, fidelity.json, figures/)")
      ->required();
  add_half_option(app, o->half, "--real (and what --rerender renders of it; a --sim recording is read whole)");
  CLI::Option* draws =
      add_draws_option(app, o->draws, "--rerender (as calibrate-noise fits them)");
  app.add_flag("--force", o->force, "replace an existing output directory");
  app.add_flag("--no-figures", o->no_figures, "skip the PNG figures");
  app.add_flag("--quiet", o->quiet, "print nothing on success");
  return [o, draws] {
    o->draws_given = draws->count() > 0;
    return run_fidelity(*o);
  };
}

}  // namespace linksight::cli
