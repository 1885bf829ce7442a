#include "run_report.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <cstdio>
#include <iomanip>

#include "cli_common.hpp"
#include "format.hpp"
#include "linksight/tracker/backend.hpp"
#include "linksight/io/error.hpp"

namespace linksight::cli {
namespace fs = std::filesystem;

namespace {

// Statistics in report units (`unit` per SI unit: 1e3 for mm or ms).
nlohmann::json stats_json(const sim::Stats& s, double unit) {
  return {{"mean", json_number(s.mean * unit)},
          {"median", json_number(s.median * unit)},
          {"p95", json_number(s.p95 * unit)},
          {"max", json_number(s.max * unit)}};
}

}  // namespace

std::set<int> choose_overlay_frames(int frames, int overlays) {
  if (overlays < 0 || overlays > 100)
    throw std::invalid_argument("--overlays = " + std::to_string(overlays) +
                                ": must be in [0, 100]");
  std::set<int> out;
  for (int i = 0; i < std::min(overlays, frames); ++i)
    out.insert(static_cast<int>((i + 0.5) * frames / overlays));
  return out;
}

std::string overlay_depth_name(int frame) {
  char name[40];
  std::snprintf(name, sizeof name, "depth_%06d.png", frame);
  return name;
}

RunReport::RunReport(const fs::path& stage, const fs::path& out, std::vector<std::string> names,
                     bool view)
    : out_(out), names_(std::move(names)), view_on_(view) {
  fs::create_directories(stage / "overlays");
  frames_.open(stage / "frames.csv");
  nodes_.open(stage / "nodes.csv");
  overlay_.open(stage / "overlays" / "nodes_px.csv");
  if (view_on_) {
    fs::create_directories(stage / "view");
    view_.open(stage / "view" / "cloud.csv");
    view_ << "frame,x_m,y_m,z_m\n" << std::setprecision(6);
  }
  if (!frames_ || !nodes_ || !overlay_ || (view_on_ && !view_))
    throw io::InputError(out_.string() + ": cannot write");
  frames_ << "mode,frame,t_s,n_points,occluded_fraction,truth_motion_mm,mean_err_mm,"
             "max_err_mm,sdf_err_mm,polyline_err_mm,swaps,reversed,reinit,init_reason,lost,"
             "time_ms\n";
  nodes_ << "mode,frame,node,x_m,y_m,z_m,true_x_m,true_y_m,true_z_m,err_mm\n";
  overlay_ << "frame,who,node,u_px,v_px\n";
  frames_ << std::setprecision(9);
  nodes_ << std::setprecision(9);
  overlay_ << std::setprecision(6);
}

void RunReport::add(const ReportFrame& f, const std::vector<FrameResult>& results,
                    const std::vector<sim::FrameScore>& scores) {
  const Nodes& truth = *f.truth_C;
  for (std::size_t k = 0; k < names_.size(); ++k) {
    const FrameResult& r = results[k];
    const sim::FrameScore& s = scores[k];
    const std::string& mode = names_[k];
    frames_ << mode << ',' << f.frame << ',' << f.t << ',' << f.n_points << ','
            << f.occluded_fraction << ',' << f.truth_motion * 1e3 << ','
            << format_fixed(s.mean_err * 1e3, 4) << ',' << format_fixed(s.max_err * 1e3, 4) << ','
            << format_fixed(r.sdf_error * 1e3, 4) << ',' << format_fixed(s.polyline * 1e3, 4) << ','
            << s.swaps << ',' << s.reversed << ',' << r.reinit << ',' << to_string(r.init_reason)
            << ',' << r.lost << ',' << format_fixed(r.time_s * 1e3, 4) << '\n';
    if (r.lost) continue;
    for (std::size_t j = 0; j < truth.size(); ++j) {
      const Eigen::Vector3d& e = r.nodes[s.reversed ? r.nodes.size() - 1 - j : j];
      const Eigen::Vector3d& t = truth[j];
      nodes_ << mode << ',' << f.frame << ',' << j << ',' << e.x() << ',' << e.y() << ','
             << e.z() << ',' << t.x() << ',' << t.y() << ',' << t.z() << ','
             << format_fixed(s.node_err[j] * 1e3, 4) << '\n';
    }
  }
  if (!frames_ || !nodes_) throw io::InputError(out_.string() + ": write failed");
}

void RunReport::overlay(const ReportFrame& f, const io::Intrinsics& K,
                        const std::vector<FrameResult>& results) {
  auto emit = [&](const std::string& who, const Nodes& nodes) {
    for (std::size_t j = 0; j < nodes.size(); ++j) {
      const Eigen::Vector2d px = K.project(nodes[j]);
      overlay_ << f.frame << ',' << who << ',' << j << ',' << px.x() << ',' << px.y() << '\n';
    }
  };
  emit("truth", *f.truth_C);
  for (std::size_t k = 0; k < names_.size(); ++k)
    if (!results[k].lost) emit(names_[k], results[k].nodes);
  if (!overlay_) throw io::InputError(out_.string() + ": write failed");
}

void RunReport::view_cloud(int frame, const Cloud& cloud) {
  if (!view_on_) return;
  const std::size_t n = cloud.size();
  const std::size_t stride = n <= kViewPoints ? 1 : (n + kViewPoints - 1) / kViewPoints;
  for (std::size_t i = 0; i < n; i += stride) {
    const float x = cloud.xyz[3 * i], y = cloud.xyz[3 * i + 1], z = cloud.xyz[3 * i + 2];
    if (check_point(x, y, z) != PointCheck::kept) continue;
    view_ << frame << ',' << x << ',' << y << ',' << z << '\n';
  }
  if (!view_) throw io::InputError(out_.string() + ": write failed");
}

void RunReport::close() {
  frames_.close();
  nodes_.close();
  overlay_.close();
  if (view_on_) view_.close();
  if (!frames_ || !nodes_ || !overlay_ || (view_on_ && !view_))
    throw io::InputError(out_.string() + ": write failed");
}

std::string draw_figures(const fs::path& dir, bool quiet) {
  std::string note =
      run_plot_script(script_path("LINKSIGHT_PLOT_SCRIPT", LINKSIGHT_PLOT_SCRIPT), dir, quiet);
  const std::string view = run_plot_script(script_path("LINKSIGHT_VIEW_SCRIPT", LINKSIGHT_VIEW_SCRIPT),
                                           dir, quiet, "python3-plotly");
  if (!view.empty()) note += (note.empty() ? "" : "; ") + view;
  return note;
}

nlohmann::json RunReport::modes_json(const std::vector<sim::EpisodeSummary>& summaries) const {
  nlohmann::json per_mode = nlohmann::json::object();
  for (std::size_t k = 0; k < names_.size(); ++k) {
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
    nlohmann::json m = nlohmann::json::object();
    for (const sim::EpisodeMetric& metric : sim::episode_metrics(s)) {
      m[metric.name] = metric.integer && !std::isnan(metric.value)
                           ? nlohmann::json(static_cast<long>(metric.value))
                           : json_number(metric.value);
    }
    m["time_ms"] = stats_json(s.time, 1e3);
    m["event_list"] = events;
    per_mode[names_[k]] = m;
  }
  return per_mode;
}

void RunReport::print_table(std::ostream& os,
                            const std::vector<sim::EpisodeSummary>& summaries) const {
  std::size_t width = 17;
  for (const std::string& n : names_) width = std::max(width, n.size() + 2);
  const auto w = static_cast<int>(width);
  os << std::left << std::setw(w) << "mode" << std::right << std::setw(10) << "mean_mm"
     << std::setw(10) << "p95_mm" << std::setw(10) << "max_mm" << std::setw(9) << "<5mm_%"
     << std::setw(8) << "reinit" << std::setw(7) << "swaps" << std::setw(10) << "time_ms"
     << "\n";
  for (std::size_t k = 0; k < names_.size(); ++k) {
    const sim::EpisodeSummary& s = summaries[k];
    os << std::left << std::setw(w) << names_[k] << std::right << std::setw(10)
       << format_fixed(s.node_err.mean * 1e3, 2) << std::setw(10)
       << format_fixed(s.node_err.p95 * 1e3, 2) << std::setw(10)
       << format_fixed(s.node_err.max * 1e3, 2) << std::setw(9)
       << format_fixed(100 * s.under_5mm, 1) << std::setw(8) << s.reinit_count << std::setw(7)
       << s.swaps << std::setw(10) << format_fixed(s.time.mean * 1e3, 2) << "\n";
  }
}

}  // namespace linksight::cli
