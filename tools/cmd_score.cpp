// linksight score: any tracker's output against a recording's truth, with exactly the
// metrics of `linksight run` (issue 18, part 1). The recording is what `linksight render`
// writes (truth.csv, occlusion.csv, clouds/, chain.json, camera.json, intrinsics.json); an
// estimate is a nodes.csv (frame,node,x_m,y_m,z_m in the camera frame, other columns
// ignored). Several estimates are scored side by side like run's --compare.
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <limits>
#include <cstdio>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <set>

#include <nlohmann/json.hpp>

#include "cli_common.hpp"
#include "commands.hpp"
#include "format.hpp"
#include "linksight/io/atomic_file.hpp"
#include "linksight/io/csv.hpp"
#include "linksight/io/error.hpp"
#include "linksight/io/intrinsics.hpp"
#include "linksight/io/nodes_csv.hpp"
#include "linksight/io/ply.hpp"
#include "linksight/sim/recording.hpp"
#include "linksight/tracker/limits.hpp"
#include "run_report.hpp"

namespace linksight::cli {
namespace {

namespace fs = std::filesystem;

struct ScoreOptions {
  std::string truth;
  std::vector<std::string> estimates;  // NAME=FILE
  std::string out;
  int overlays = 4;
  bool figures = true;
  bool force = false;
  bool quiet = false;
};

struct Estimate {
  std::string name;
  fs::path file;
  std::vector<std::optional<Nodes>> frames;
};

// NAME=FILE; a name is what the tables and figures call the estimate.
Estimate parse_estimate(const std::string& text) {
  const std::size_t eq = text.find('=');
  const std::string name = text.substr(0, eq);
  if (eq == std::string::npos || eq + 1 == text.size())
    throw std::invalid_argument("--estimate '" + io::echo(text) + "': expected NAME=FILE");
  bool ok = !name.empty() && name.size() <= 40 && name != "truth";
  for (const char c : name)
    ok = ok && (std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.');
  if (!ok)
    throw std::invalid_argument("--estimate '" + io::echo(text) + "': the name '" + io::echo(name) +
                                "' must be 1-40 letters, digits, '-', '_' or '.', not 'truth'");
  return {name, text.substr(eq + 1), {}};
}

// The link's occluded fraction per frame, as the sensor computes it: one minus the
// visible over the unoccluded pixels, summed over the components (each once per frame).
std::vector<double> read_occlusion(const fs::path& path, std::size_t frames, int components) {
  const std::string file = path.string();
  io::CsvLimits limits;  // a row per frame and component
  limits.max_rows = io::rows_with_room(frames * static_cast<std::size_t>(components));
  const io::CsvTable t = io::read_csv(path, limits);
  constexpr int kCols = 4;
  std::size_t at[kCols] = {0, 0, 0, 0};
  const char* names[kCols] = {"frame", "component", "visible_px", "visible_px_unoccluded"};
  for (int c = 0; c < kCols; ++c) {
    const auto it = std::find(t.header.begin(), t.header.end(), names[c]);
    if (it == t.header.end()) throw io::InputError(file + ":1: no column '" + names[c] + "'");
    at[c] = static_cast<std::size_t>(it - t.header.begin());
  }
  const auto n = static_cast<std::size_t>(components);
  std::vector<long> vis(frames, 0), unocc(frames, 0);
  std::vector<int> line_of(frames * n, 0);
  for (std::size_t r = 0; r < t.rows.size(); ++r) {
    const std::string where = file + ":" + std::to_string(t.lines[r]) + ": ";
    long v[kCols] = {0, 0, 0, 0};
    for (int c = 0; c < kCols; ++c) {
      const std::string& s = t.rows[r][at[c]];
      const auto res = std::from_chars(s.data(), s.data() + s.size(), v[c]);
      if (res.ec != std::errc() || res.ptr != s.data() + s.size() || v[c] < 0 ||
          v[c] > 1'000'000'000)
        throw io::InputError(where + names[c] + " '" + io::echo(s) + "' is not a count");
    }
    const auto f = static_cast<std::size_t>(v[0]), k = static_cast<std::size_t>(v[1]);
    if (f >= frames)
      throw io::InputError(where + "frame " + std::to_string(f) + " is not among the truth's " +
                           std::to_string(frames) + " frames");
    if (k >= n)
      throw io::InputError(where + "component " + std::to_string(k) + " is not among the " +
                           std::to_string(n) + " of chain.json");
    if (line_of[f * n + k] != 0)
      throw io::InputError(where + "frame " + std::to_string(f) + " component " +
                           std::to_string(k) + " given twice (first on line " +
                           std::to_string(line_of[f * n + k]) + ")");
    line_of[f * n + k] = t.lines[r];
    vis[f] += v[2];
    unocc[f] += v[3];
  }
  std::vector<double> out(frames, 0.0);
  for (std::size_t f = 0; f < frames; ++f) {
    for (std::size_t k = 0; k < n; ++k)
      if (line_of[f * n + k] == 0)
        throw io::InputError(file + ": frame " + std::to_string(f) + " component " +
                             std::to_string(k) + " has no row");
    out[f] = unocc[f] > 0 ? 1.0 - static_cast<double>(vis[f]) / static_cast<double>(unocc[f])
                          : 0.0;
  }
  return out;
}

// truth.csv's time of each frame [s] (the physics' own, which run reports).
std::vector<double> read_truth_times(const fs::path& path, std::size_t frames, std::size_t rows) {
  const std::string file = path.string();
  io::CsvLimits limits;
  limits.max_rows = io::rows_with_room(rows);
  const io::CsvTable t = io::read_csv(path, limits);
  const auto f_at = std::find(t.header.begin(), t.header.end(), "frame");
  const auto t_at = std::find(t.header.begin(), t.header.end(), "t_s");
  if (t_at == t.header.end()) throw io::InputError(file + ":1: no column 't_s'");
  std::vector<double> out(frames, 0.0);
  for (std::size_t r = 0; r < t.rows.size(); ++r) {
    const std::string& fs = t.rows[r][static_cast<std::size_t>(f_at - t.header.begin())];
    const std::string& ts = t.rows[r][static_cast<std::size_t>(t_at - t.header.begin())];
    std::size_t f = 0;
    double v = 0;
    // The frame was checked by read_nodes_csv.
    (void)std::from_chars(fs.data(), fs.data() + fs.size(), f);
    const auto res = std::from_chars(ts.data(), ts.data() + ts.size(), v);
    if (res.ec != std::errc() || res.ptr != ts.data() + ts.size() || !std::isfinite(v))
      throw io::InputError(file + ":" + std::to_string(t.lines[r]) + ": t_s '" + io::echo(ts) +
                           "' is not a finite number");
    if (f < frames) out[f] = v;
  }
  return out;
}

int run_score(const ScoreOptions& o) {
  if (o.estimates.empty()) throw std::invalid_argument("--estimate: give at least one NAME=FILE");
  std::vector<Estimate> estimates;
  std::set<std::string> names_seen;
  for (const std::string& e : o.estimates) {
    estimates.push_back(parse_estimate(e));
    if (!names_seen.insert(estimates.back().name).second)
      throw std::invalid_argument("--estimate '" + io::echo(e) + "': the name '" +
                                  estimates.back().name + "' is given twice");
  }
  const fs::path truth_dir(o.truth);
  std::error_code ec;
  if (!fs::is_directory(truth_dir, ec))
    throw io::InputError(o.truth + ": not a directory (--truth: a recording from `linksight "
                                   "render`)");
  // --force replaces --out: never the recording, nor a directory holding it or in it.
  {
    const fs::path t = fs::weakly_canonical(truth_dir, ec);
    const fs::path u = ec ? fs::path() : fs::weakly_canonical(fs::path(o.out), ec);
    const auto within = [](const fs::path& a, const fs::path& b) {  // a is b or inside b
      auto ai = a.begin(), bi = b.begin();
      for (; bi != b.end() && !bi->empty(); ++ai, ++bi)
        if (ai == a.end() || *ai != *bi) return false;
      return true;
    };
    if (!ec && (within(u, t) || within(t, u)))
      throw std::invalid_argument("--out " + o.out + ": must not be or hold the recording (--truth " +
                                  o.truth + ")");
  }
  // Everything is read and checked before any output exists.
  const ComponentGeometry geometry = sim::read_chain_json(truth_dir / "chain.json");
  const double fps = sim::read_camera_fps(truth_dir / "camera.json");
  const io::Intrinsics K = io::read_intrinsics(truth_dir / "intrinsics.json");
  // The truth's rows: a node per ball and the tip, for each frame of the longest scene.
  const std::size_t truth_rows = (static_cast<std::size_t>(sim::kMaxDurationS * fps) + 1) *
                                 (static_cast<std::size_t>(geometry.count) + 1);
  const std::vector<std::optional<Nodes>> truth =
      io::read_nodes_csv(truth_dir / "truth.csv", 0, 0, truth_rows);
  const std::size_t frames = truth.size();
  if (frames == 0) throw io::InputError((truth_dir / "truth.csv").string() + ": no frames");
  for (std::size_t f = 0; f < frames; ++f)
    if (!truth[f])
      throw io::InputError((truth_dir / "truth.csv").string() + ": frame " + std::to_string(f) +
                           " has no rows");
  const std::size_t n_nodes = truth[0]->size();
  if (n_nodes != static_cast<std::size_t>(geometry.count) + 1)
    throw io::InputError((truth_dir / "truth.csv").string() + ": " + std::to_string(n_nodes) +
                         " nodes per frame, but chain.json has count " +
                         std::to_string(geometry.count) + " (a node per ball and the tip: " +
                         std::to_string(geometry.count + 1) + ")");
  const std::vector<double> times = read_truth_times(truth_dir / "truth.csv", frames, truth_rows);
  const std::vector<double> occluded = read_occlusion(truth_dir / "occlusion.csv", frames, geometry.count);
  for (Estimate& e : estimates) e.frames = io::read_nodes_csv(e.file, frames, n_nodes);
  std::vector<fs::path> clouds(frames);
  for (std::size_t f = 0; f < frames; ++f) {
    char name[32];
    std::snprintf(name, sizeof name, "%06zu.ply", f);
    clouds[f] = truth_dir / "clouds" / name;
    if (!fs::is_regular_file(clouds[f], ec))
      throw io::InputError(clouds[f].string() + ": no such file (the recording's cloud of frame " +
                           std::to_string(f) + ")");
  }
  const std::set<int> overlay_frames =
      choose_overlay_frames(static_cast<int>(frames), o.overlays);

  const fs::path out(o.out);
  io::StagedDir dir(out, o.force);
  const fs::path stage = dir.path();
  std::vector<std::string> names;
  for (const Estimate& e : estimates) names.push_back(e.name);
  RunReport report(stage, out, names, o.figures);
  std::vector<sim::EpisodeScorer> scorers(estimates.size());
  std::vector<FrameResult> results(estimates.size());
  std::vector<sim::FrameScore> scores(estimates.size());
  for (std::size_t f = 0; f < frames; ++f) {
    const Cloud cloud = io::read_ply(clouds[f]);
    const Nodes& truth_C = *truth[f];
    double motion = 0;
    if (f > 0)
      for (std::size_t j = 0; j < n_nodes; ++j)
        motion = std::max(motion, (truth_C[j] - (*truth[f - 1])[j]).norm());
    for (std::size_t k = 0; k < estimates.size(); ++k) {
      FrameResult& r = results[k];
      r = FrameResult{};
      // No time: the tracker ran elsewhere.
      r.time_s = std::numeric_limits<double>::quiet_NaN();
      const std::optional<Nodes>& e = estimates[k].frames[f];
      r.lost = !e;  // a frame the estimate does not give is lost, not an error
      r.nodes = e ? *e : Nodes{};
      // The SDF metric over the points a tracker keeps, as a built-in mode reports it.
      r.sdf_error = e ? sim::cloud_sdf_error(cloud, r.nodes, geometry)
                      : std::numeric_limits<double>::quiet_NaN();
      scores[k] = sim::score_frame(r.nodes, truth_C);
      scorers[k].add(scores[k], r.sdf_error, false, r.time_s, occluded[f], motion);
    }
    const ReportFrame rf{static_cast<int>(f), times[f], cloud.size(),
                         occluded[f], motion, &truth_C};
    report.add(rf, results, scores);
    report.view_cloud(static_cast<int>(f), cloud);
    if (overlay_frames.count(static_cast<int>(f))) {
      char name[32];
      std::snprintf(name, sizeof name, "%06zu.png", f);
      const fs::path depth = truth_dir / "depth" / name;
      ec.clear();
      if (fs::is_regular_file(depth, ec))
        fs::copy_file(depth, stage / "overlays" / overlay_depth_name(static_cast<int>(f)), ec);
      if (ec) throw io::InputError(out.string() + ": cannot copy " + depth.string());
      report.overlay(rf, K, results);
    }
  }
  report.close();

  std::vector<sim::EpisodeSummary> summaries;
  for (const sim::EpisodeScorer& s : scorers) summaries.push_back(s.summary());
  nlohmann::json files = nlohmann::json::object();
  for (const Estimate& e : estimates) files[e.name] = e.file.string();
  nlohmann::json summary = {{"truth", o.truth},
                            {"estimates", files},
                            {"frames", frames},
                            {"fps", fps},
                            {"modes", report.modes_json(summaries)}};
  io::write_file_atomic(stage / "summary.json", [&](std::ostream& os) {
    os << summary.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) << "\n";
  });
  std::string figures_note;
  if (o.figures)
    figures_note = draw_figures(stage, o.quiet);
  dir.commit();
  if (!figures_note.empty())
    std::cerr << "linksight: warning: " << io::printable_line(figures_note) << "\n";
  if (!o.quiet) {
    std::cout << "scored " << estimates.size() << " estimate" << (estimates.size() > 1 ? "s" : "")
              << " against " << frames << " frames of " << o.truth << "\n";
    report.print_table(std::cout, summaries);
    std::cout << "wrote " << out.string() << "/{frames.csv,nodes.csv,summary.json}"
              << (figures_note.empty() && o.figures
                      ? ", figures in " + out.string() + "/figures/, 3-D view " + out.string() + "/view.html"
                                                    : std::string())
              << "\n";
  }
  return kExitOk;
}

}  // namespace

Runner add_score(CLI::App& app) {
  auto o = std::make_shared<ScoreOptions>();
  app.add_option("--truth", o->truth,
                 "a recording from `linksight render` (truth.csv, occlusion.csv, clouds/, "
                 "chain.json, camera.json, intrinsics.json)")
      ->required();
  app.add_option("--estimate", o->estimates,
                 "NAME=FILE (repeatable): a tracker's nodes.csv with columns frame,node,x_m,y_m,"
                 "z_m (camera frame; other columns ignored); a frame it does not give is lost")
      ->required();
  app.add_option("--out", o->out, "output directory")->required();
  app.add_option("--overlays", o->overlays, "frames with an overlay figure")
      ->capture_default_str();
  app.add_flag("!--no-figures", o->figures, "skip the figures (tools/plot_run.py)");
  app.add_flag("--force", o->force, "replace an existing output directory");
  app.add_flag("--quiet", o->quiet, "no summary table");
  return [o] { return run_score(*o); };
}

}  // namespace linksight::cli
