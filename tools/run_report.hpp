#pragma once
// What a scored episode writes, as `run` writes it from the trackers it ran and `score`
// from estimates on disk: frames.csv, nodes.csv, overlays/nodes_px.csv, the per-mode block
// of summary.json and the table on stdout. One writer, so that both commands' files have
// the same columns and keys and tools/plot_run.py draws either.

#include <filesystem>
#include <fstream>
#include <ostream>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "linksight/io/intrinsics.hpp"
#include "linksight/sim/score.hpp"
#include "linksight/tracker/tracker.hpp"

namespace linksight::cli {

/// One frame's facts that do not depend on the tracker.
struct ReportFrame {
  int frame = 0;
  double t = 0;                 ///< [s]
  std::size_t n_points = 0;     ///< of the cloud the trackers were given
  double occluded_fraction = 0; ///< of the link
  double truth_motion = 0;      ///< largest true node displacement since the last frame [m]
  const Nodes* truth_C = nullptr;  ///< true nodes, camera frame [m]
};

/// Points per frame in the 3-D view: 240 frames of them and plotly.js stay under 20 MB.
inline constexpr std::size_t kViewPoints = 1500;

class RunReport {
 public:
  /// Opens the tables in `stage` (a staging directory; `out` is its final name, for
  /// messages) for the modes `names`, in the order results are given; with `view`, also
  /// view/cloud.csv for the 3-D view (view_cloud).
  RunReport(const std::filesystem::path& stage, const std::filesystem::path& out,
            std::vector<std::string> names, bool view);
  /// One frame: per mode its result (nodes, lost, reinit, init_reason, sdf_error, time_s)
  /// and score. Throws io::InputError when a write fails.
  void add(const ReportFrame& f, const std::vector<FrameResult>& results,
           const std::vector<sim::FrameScore>& scores);
  /// An overlay frame's projected nodes (truth and each mode not lost) for plot_run.py;
  /// its depth image, overlays/depth_NNNNNN.png, is the caller's to write.
  void overlay(const ReportFrame& f, const io::Intrinsics& K,
               const std::vector<FrameResult>& results);
  /// The frame's cloud for the 3-D view (view/cloud.csv): every k-th finite point, at most
  /// kViewPoints a frame. Nothing without `view`.
  void view_cloud(int frame, const Cloud& cloud);
  /// Flushes and closes the tables; throws io::InputError when a write failed.
  void close();

  /// summary.json's "modes": per mode the metrics under the names sweep's tables use
  /// (sim::episode_metrics), then time_ms and the event list.
  [[nodiscard]] nlohmann::json modes_json(const std::vector<sim::EpisodeSummary>& s) const;
  /// The summary table a command prints.
  void print_table(std::ostream& os, const std::vector<sim::EpisodeSummary>& s) const;

 private:
  std::filesystem::path out_;
  std::vector<std::string> names_;
  bool view_on_;
  std::ofstream frames_, nodes_, overlay_, view_;
};

/// The figures (tools/plot_run.py) and the 3-D view (tools/plot_view.py, view.html) of the
/// run directory `dir`: "" when both were drawn, else a note saying what is missing and
/// why (the data files are complete either way).
[[nodiscard]] std::string draw_figures(const std::filesystem::path& dir, bool quiet);

/// `overlays` frames spread evenly over `frames` (each at the middle of its share).
/// Throws std::invalid_argument naming --overlays unless 0 <= overlays <= 100.
[[nodiscard]] std::set<int> choose_overlay_frames(int frames, int overlays);

/// An overlay depth image's name in overlays/: depth_NNNNNN.png.
[[nodiscard]] std::string overlay_depth_name(int frame);

}  // namespace linksight::cli
