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
#include "run_report.hpp"
#include "linksight/io/atomic_file.hpp"
#include "linksight/io/depth_png.hpp"
#include "linksight/io/error.hpp"
#include "linksight/sim/episode.hpp"
#include "linksight/sim/scene.hpp"

namespace linksight::cli {
namespace {

namespace fs = std::filesystem;


struct RunOptions {
  std::string scene;
  std::string out;  // empty: out/run/<scene name>
  std::vector<std::string> set;
  std::string compare;  // empty: the scene's mode (and every --tracker)
  std::vector<std::string> trackers;  // --tracker NAME=COMMAND
  int frames = 0;
  int threads = 0;
  int overlays = 4;
  bool figures = true;
  bool force = false;
  bool quiet = false;
  bool print_scene = false;
};

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
  (void)choose_overlay_frames(0, o.overlays);  // --overlays is checked before anything runs
  if (o.print_scene) {
    std::cout << sim::resolved_scene_yaml(o.scene, o.set);
    return kExitOk;
  }
  // From here a Ctrl-C or SIGTERM ends the run cleanly: the frames done are written, the
  // external trackers ended, nothing left in a staging directory.
  const InterruptGuard guard;
  const sim::Scene scene = sim::load_scene(o.scene, o.set);
  sim::EpisodeOptions eo;
  eo.cancel = &interrupted();
  eo.frames = o.frames;
  eo.threads = o.threads;
  eo.scene_mode = split_compare(o.compare, o.trackers, eo.modes, eo.external);
  const std::set<int> overlay_frames =
      choose_overlay_frames(sim::camera_frames(scene, o.frames), o.overlays);
  // Nothing but the overlays' depth images is written, so the other frames need only the
  // pixels their clouds come from.
  eo.chain_only_images = true;
  eo.whole_frames.assign(overlay_frames.begin(), overlay_frames.end());
  sim::Episode episode(scene, eo);  // a missing mesh fails here, before any output
  const fs::path out = o.out.empty() ? fs::path("out/run") / fs::path(o.scene).stem() : fs::path(o.out);
  io::StagedDir dir(out, o.force);
  const fs::path stage = dir.path();
  const std::vector<std::string> names = episode.names();
  RunReport report(stage, out, names, o.figures);
  // Per tracker, its lost frames' reasons in words (external trackers).
  std::vector<nlohmann::json> lost_notes(names.size(), nlohmann::json::array());

  const int n = episode.frames();
  const io::Intrinsics& K = scene.camera.intrinsics;

  const bool bar = !o.quiet && isatty(fileno(stderr));
  const auto t_start = std::chrono::steady_clock::now();
  double physics = 0, render = 0, extract = 0;
  while (episode.done() < n && !interrupted()) {
    const sim::EpisodeFrame* step = nullptr;
    try {
      step = &episode.step();
    } catch (const sim::ExternalTrackerInterrupted&) {
      break;  // that frame is not scored; the frames before it are written
    }
    const sim::EpisodeFrame& f = *step;
    physics += episode.last_times().physics;
    render += episode.last_times().render;
    extract += episode.last_times().extract;
    const ReportFrame rf{f.frame, f.t, f.cloud->size(), f.image->link_occluded_fraction,
                         f.truth_motion, &f.truth_C};
    report.add(rf, f.results, f.scores);
    report.view_cloud(f.frame, *f.cloud);
    for (std::size_t k = 0; k < names.size(); ++k)
      if (!f.lost_details[k].empty())
        lost_notes[k].push_back({{"frame", f.frame}, {"reason", f.lost_details[k]}});
    if (overlay_frames.count(f.frame)) {
      io::write_depth_png(stage / "overlays" / overlay_depth_name(f.frame), f.image->depth);
      report.overlay(rf, K, f.results);
    }
    if (bar)
      progress(episode.done(), n,
               std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count());
  }
  episode.stop_external();  // the external trackers end here, not after the figures
  const double wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  if (bar) std::cerr << "\n";
  report.close();

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
  summary["modes"] = report.modes_json(summaries);
  for (std::size_t k = 0; k < eo.external.size(); ++k) {
    const std::size_t at = names.size() - eo.external.size() + k;
    summary["modes"][names[at]]["external"] = {{"command", eo.external[k].command},
                                               {"lost_frames", lost_notes[at]}};
  }
  io::write_file_atomic(stage / "summary.json", [&](std::ostream& os) {
    os << summary.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) << "\n";
  });

  // Figures: matplotlib via tools/plot_run.py, into the staged directory.
  std::string figures_note;
  if (o.figures && done > 0) {
    figures_note = draw_figures(stage, o.quiet);
  }
  dir.commit();

  if (!figures_note.empty())
    std::cerr << "linksight: warning: " << io::printable_line(figures_note) << "\n";
  if (!o.quiet) {
    std::cout << (done < n ? "interrupted after " : "ran ") << done << " frames of " << o.scene
              << " (" << format_fixed(done / std::max(wall, 1e-9), 1) << " frames/s)\n";
    report.print_table(std::cout, summaries);
    for (std::size_t k = 0; k < names.size(); ++k)
      if (!lost_notes[k].empty())
        std::cerr << io::printable_line("linksight: warning: " + names[k] + ": " +
                                        std::to_string(lost_notes[k].size()) +
                                        " frame(s) lost, the first (frame " +
                                        std::to_string(lost_notes[k][0]["frame"].get<int>()) +
                                        "): " + lost_notes[k][0]["reason"].get<std::string>() +
                                        " (all in summary.json)")
                  << "\n";
    std::cout << "wrote " << out.string() << "/{frames.csv,nodes.csv,summary.json}"
              << (figures_note.empty() && o.figures
                      ? ", figures in " + out.string() + "/figures/, 3-D view " + out.string() + "/view.html"
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
                 "trackers to run on the same frames, comma-separated: modes (" +
                     mode_choices() + ") and --tracker NAMEs; the modes come first in the "
                     "tables (default: the scene's tracker.mode and every --tracker)");
  app.add_option("--tracker", o->trackers,
                 "NAME=COMMAND (repeatable): a tracker outside linksight, started once per "
                 "episode with /bin/sh -c COMMAND and fed each frame on its stdin "
                 "(docs/protocol.md); compare it by NAME in --compare");
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
