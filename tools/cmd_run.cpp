// linksight run: the main job. A scene goes in; physics, the simulated SR300, every
// compared tracker mode on the same frames and the scoring come out as frames.csv,
// nodes.csv, summary.json, overlay data and figures (tools/plot_run.py).
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <csignal>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <memory>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "cli_common.hpp"
#include "commands.hpp"
#include "format.hpp"
#include "linksight/io/atomic_file.hpp"
#include "linksight/io/depth_png.hpp"
#include "linksight/io/error.hpp"
#include "linksight/sim/episode.hpp"
#include "linksight/sim/scene.hpp"

namespace linksight::cli {
namespace {

namespace fs = std::filesystem;

std::atomic<bool> g_interrupted{false};
extern "C" void on_sigint(int) { g_interrupted = true; }

struct RunOptions {
  std::string scene;
  std::string out;  // empty: out/run/<scene name>
  std::vector<std::string> set;
  std::string compare;  // empty: the scene's mode
  int frames = 0;
  int threads = 0;
  int overlays = 4;
  bool figures = true;
  bool force = false;
  bool quiet = false;
  bool print_scene = false;
};

// Statistics in report units (`unit` per SI unit: 1e3 for mm or ms).
nlohmann::json stats_json(const sim::Stats& s, double unit) {
  return {{"mean", json_number(s.mean * unit)},
          {"median", json_number(s.median * unit)},
          {"p95", json_number(s.p95 * unit)},
          {"max", json_number(s.max * unit)}};
}

// A progress bar on a terminal: frames done, rate, time left.
void progress(int done, int total, double elapsed_s) {
  constexpr int kWidth = 30;
  const int filled = total > 0 ? done * kWidth / total : kWidth;
  const double rate = elapsed_s > 0 ? done / elapsed_s : 0;
  std::cerr << "\r[" << std::string(filled, '#') << std::string(kWidth - filled, '.') << "] "
            << done << "/" << total << " frames, " << format_fixed(rate, 1) << " frames/s";
  if (rate > 0) std::cerr << ", " << format_fixed((total - done) / rate, 0) << " s left ";
  std::cerr << std::flush;
}

int run_run(const RunOptions& o) {
  if (o.frames < 0)
    throw std::invalid_argument("--frames = " + std::to_string(o.frames) + ": must be >= 0");
  if (o.threads < 0)
    throw std::invalid_argument("--threads = " + std::to_string(o.threads) + ": must be >= 0");
  if (o.overlays < 0 || o.overlays > 100)
    throw std::invalid_argument("--overlays = " + std::to_string(o.overlays) +
                                ": must be in [0, 100]");
  if (o.print_scene) {
    std::cout << sim::resolved_scene_yaml(o.scene, o.set);
    return kExitOk;
  }
  const sim::Scene scene = sim::load_scene(o.scene, o.set);
  sim::EpisodeOptions eo;
  eo.frames = o.frames;
  eo.threads = o.threads;
  if (!o.compare.empty()) eo.modes = parse_compare(o.compare);
  std::set<int> overlay_frames;
  {
    const int n = sim::camera_frames(scene, o.frames);
    for (int i = 0; i < std::min(o.overlays, n); ++i)
      overlay_frames.insert(static_cast<int>((i + 0.5) * n / o.overlays));
  }
  // Nothing but the overlays' depth images is written, so the other frames need only the
  // pixels their clouds come from.
  eo.chain_only_images = true;
  eo.whole_frames.assign(overlay_frames.begin(), overlay_frames.end());
  sim::Episode episode(scene, eo);  // a missing mesh fails here, before any output
  const fs::path out = o.out.empty() ? fs::path("out/run") / fs::path(o.scene).stem() : fs::path(o.out);
  io::StagedDir dir(out, o.force);
  const fs::path stage = dir.path();
  fs::create_directories(stage / "overlays");

  std::ofstream frames_csv(stage / "frames.csv"), nodes_csv(stage / "nodes.csv"),
      overlay_csv(stage / "overlays" / "nodes_px.csv");
  if (!frames_csv || !nodes_csv || !overlay_csv)
    throw io::InputError(out.string() + ": cannot write");
  frames_csv << "mode,frame,t_s,n_points,occluded_fraction,truth_motion_mm,mean_err_mm,"
                "max_err_mm,sdf_err_mm,polyline_err_mm,swaps,reversed,reinit,init_reason,lost,"
                "time_ms\n";
  nodes_csv << "mode,frame,node,x_m,y_m,z_m,true_x_m,true_y_m,true_z_m,err_mm\n";
  overlay_csv << "frame,who,node,u_px,v_px\n";
  frames_csv << std::setprecision(9);
  nodes_csv << std::setprecision(9);
  overlay_csv << std::setprecision(6);

  const int n = episode.frames();
  const auto& modes = episode.modes();
  const io::Intrinsics& K = scene.camera.intrinsics;

  const bool bar = !o.quiet && isatty(fileno(stderr));
  g_interrupted = false;
  auto* previous_handler = std::signal(SIGINT, on_sigint);
  const auto t_start = std::chrono::steady_clock::now();
  double physics = 0, render = 0, extract = 0;
  while (episode.done() < n && !g_interrupted) {
    const sim::EpisodeFrame& f = episode.step();
    physics += episode.last_times().physics;
    render += episode.last_times().render;
    extract += episode.last_times().extract;
    for (std::size_t k = 0; k < modes.size(); ++k) {
      const FrameResult& r = f.results[k];
      const sim::FrameScore& s = f.scores[k];
      const std::string mode(to_string(modes[k]));
      frames_csv << mode << ',' << f.frame << ',' << f.t << ',' << f.cloud->size() << ','
                 << f.image->link_occluded_fraction << ',' << f.truth_motion * 1e3 << ','
                 << format_fixed(s.mean_err * 1e3, 4) << ',' << format_fixed(s.max_err * 1e3, 4) << ','
                 << format_fixed(r.sdf_error * 1e3, 4) << ',' << format_fixed(s.polyline * 1e3, 4) << ','
                 << s.swaps << ',' << s.reversed << ',' << r.reinit << ','
                 << to_string(r.init_reason) << ',' << r.lost << ',' << format_fixed(r.time_s * 1e3, 4)
                 << '\n';
      if (!r.lost) {
        for (std::size_t j = 0; j < f.truth_C.size(); ++j) {
          const Eigen::Vector3d& e = r.nodes[s.reversed ? r.nodes.size() - 1 - j : j];
          const Eigen::Vector3d& t = f.truth_C[j];
          nodes_csv << mode << ',' << f.frame << ',' << j << ',' << e.x() << ',' << e.y() << ','
                    << e.z() << ',' << t.x() << ',' << t.y() << ',' << t.z() << ','
                    << format_fixed(s.node_err[j] * 1e3, 4) << '\n';
        }
      }
    }
    if (overlay_frames.count(f.frame)) {
      char name[40];
      std::snprintf(name, sizeof name, "depth_%06d.png", f.frame);
      io::write_depth_png(stage / "overlays" / name, f.image->depth);
      auto emit = [&](const std::string& who, const Nodes& nodes) {
        for (std::size_t j = 0; j < nodes.size(); ++j) {
          const Eigen::Vector2d px = K.project(nodes[j]);
          overlay_csv << f.frame << ',' << who << ',' << j << ',' << px.x() << ',' << px.y()
                      << '\n';
        }
      };
      emit("truth", f.truth_C);
      for (std::size_t k = 0; k < modes.size(); ++k)
        if (!f.results[k].lost) emit(std::string(to_string(modes[k])), f.results[k].nodes);
    }
    if (!frames_csv || !nodes_csv || !overlay_csv)
      throw io::InputError(out.string() + ": write failed");
    if (bar)
      progress(episode.done(), n,
               std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count());
  }
  std::signal(SIGINT, previous_handler);
  const double wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  if (bar) std::cerr << "\n";
  frames_csv.close();
  nodes_csv.close();
  overlay_csv.close();
  if (!frames_csv || !nodes_csv || !overlay_csv)
    throw io::InputError(out.string() + ": write failed");

  // summary.json
  const int done = episode.done();
  const std::vector<sim::EpisodeSummary> summaries = episode.summaries();
  nlohmann::json summary = {
      {"scene", o.scene},
      {"overrides", o.set},
      {"seed", scene.seed},
      {"frames", done},
      {"frames_planned", n},
      {"interrupted", done < n},
      {"fps", scene.camera.fps},
      {"timing_ms_per_frame",
       {{"physics", done ? physics / done * 1e3 : 0.0},
        {"render", done ? render / done * 1e3 : 0.0},
        {"extract", done ? extract / done * 1e3 : 0.0},
        {"wall", done ? wall / done * 1e3 : 0.0}}},
  };
  nlohmann::json per_mode = nlohmann::json::object();
  for (std::size_t k = 0; k < modes.size(); ++k) {
    const sim::EpisodeSummary& s = summaries[k];
    nlohmann::json events = nlohmann::json::array();
    for (const sim::Event& e : s.events) {
      events.push_back({{"kind", sim::to_string(e.kind)},
                        {"start_frame", e.start},
                        {"end_frame", e.end},
                        {"frames_to_recover", e.frames_to_recover >= 0
                                                  ? nlohmann::json(e.frames_to_recover)
                                                  : nlohmann::json(nullptr)}});
    }
    // The metrics under the names sweep's tables use (sim::episode_metrics), then timing
    // and the events.
    nlohmann::json m = nlohmann::json::object();
    for (const sim::EpisodeMetric& metric : sim::episode_metrics(s)) {
      m[metric.name] = metric.integer && !std::isnan(metric.value)
                           ? nlohmann::json(static_cast<long>(metric.value))
                           : json_number(metric.value);
    }
    m["time_ms"] = stats_json(s.time, 1e3);
    m["event_list"] = events;
    per_mode[std::string(to_string(modes[k]))] = m;
  }
  summary["modes"] = per_mode;
  io::write_file_atomic(stage / "summary.json", [&](std::ostream& os) {
    os << summary.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) << "\n";
  });

  // Figures: matplotlib via tools/plot_run.py, into the staged directory.
  std::string figures_note;
  if (o.figures && done > 0) {
    figures_note = run_plot_script(script_path("LINKSIGHT_PLOT_SCRIPT", LINKSIGHT_PLOT_SCRIPT),
                                   stage, o.quiet);
  }
  dir.commit();

  if (!figures_note.empty()) std::cerr << "linksight: warning: " << figures_note << "\n";
  if (!o.quiet) {
    std::cout << (done < n ? "interrupted after " : "ran ") << done << " frames of " << o.scene
              << " (" << format_fixed(done / std::max(wall, 1e-9), 1) << " frames/s)\n";
    std::cout << std::left << std::setw(17) << "mode" << std::right << std::setw(10)
              << "mean_mm" << std::setw(10) << "p95_mm" << std::setw(10) << "max_mm"
              << std::setw(9) << "<5mm_%" << std::setw(8) << "reinit" << std::setw(7) << "swaps"
              << std::setw(10) << "time_ms" << "\n";
    for (std::size_t k = 0; k < modes.size(); ++k) {
      const sim::EpisodeSummary& s = summaries[k];
      std::cout << std::left << std::setw(17) << to_string(modes[k]) << std::right
                << std::setw(10) << format_fixed(s.node_err.mean * 1e3, 2) << std::setw(10)
                << format_fixed(s.node_err.p95 * 1e3, 2) << std::setw(10)
                << format_fixed(s.node_err.max * 1e3, 2) << std::setw(9)
                << format_fixed(100 * s.under_5mm, 1) << std::setw(8) << s.reinit_count
                << std::setw(7) << s.swaps << std::setw(10) << format_fixed(s.time.mean * 1e3, 2)
                << "\n";
    }
    std::cout << "wrote " << out.string() << "/{frames.csv,nodes.csv,summary.json}"
              << (figures_note.empty() && o.figures ? ", figures in " + out.string() + "/figures/"
                                                    : std::string())
              << "\n";
  }
  return done < n ? 130 : kExitOk;
}

}  // namespace

Runner add_run(CLI::App& app) {
  auto o = std::make_shared<RunOptions>();
  app.add_option("scene", o->scene, "scene file (YAML), e.g. scenes/default.yaml")->required();
  app.add_option("--out", o->out, "output directory (default: out/run/<scene name>)");
  app.add_option("--set", o->set,
                 "override a scene key: key.path=value (repeatable), e.g. --set camera.fps=60 "
                 "--set 'occluders[0].reflectance=0.5'");
  app.add_option("--compare", o->compare,
                 "tracker modes to run on the same frames, comma-separated, of: " +
                     mode_choices() + " (default: the scene's tracker.mode)");
  app.add_option("--frames", o->frames, "camera frames (0: the scene's duration)")
      ->capture_default_str();
  app.add_option("--threads", o->threads, "OpenMP threads for the sensor (0: default)")
      ->capture_default_str();
  app.add_option("--overlays", o->overlays, "frames with an overlay figure")
      ->capture_default_str();
  app.add_flag("!--no-figures", o->figures, "skip the figures (tools/plot_run.py)");
  app.add_flag("--force", o->force, "replace an existing output directory");
  app.add_flag("--quiet", o->quiet, "no progress bar and no summary table");
  app.add_flag("--print-scene", o->print_scene,
               "print the scene as read (every parameter block in full, --set applied) as "
               "YAML and exit; it loads back to the same scene");
  return [o] { return run_run(*o); };
}

}  // namespace linksight::cli
