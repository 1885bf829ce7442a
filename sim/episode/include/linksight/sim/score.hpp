#pragma once
/// @file Scoring a tracker's output against the true nodes: per frame, and per episode
/// (error statistics, events and recovery, timing). Everything in metres and seconds;
/// reports convert to millimetres and milliseconds.

#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "linksight/tracker/cloud.hpp"
#include "linksight/tracker/geometry.hpp"
#include "linksight/tracker/model.hpp"

namespace linksight::sim {

inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// Distance from `p` to the polyline through `nodes` (segments between neighbours) [m].
[[nodiscard]] double point_to_polyline(const Eigen::Vector3d& p, const Nodes& nodes);

/// TrackDLO's bidirectional point-to-polyline distance (Xiang et al., RA-L 2023): the
/// mean of (mean distance of a's nodes to b's polyline) and (mean distance of b's nodes
/// to a's polyline) [m]. Zero only when each polyline's nodes lie on the other.
[[nodiscard]] double bidirectional_polyline_distance(const Nodes& a, const Nodes& b);

/// Topology check: the order inversions among the estimated ball nodes (all but the
/// last, the tip), each read as the index of its nearest true ball: pairs j < k whose
/// nearest balls come in the other order. Two neighbouring nodes trading places count 1.
/// A node pulled onto its neighbour's ball (a hidden ball's node, say) keeps the order and
/// is no swap; misassigned_nodes counts it. The tip has no material at its true position
/// (one pitch beyond the last ball) and is scored by its node error only.
[[nodiscard]] int topology_swaps(const Nodes& estimate, const Nodes& truth);
/// Estimated ball nodes j whose nearest true ball is not j.
[[nodiscard]] int misassigned_nodes(const Nodes& estimate, const Nodes& truth);

/// One tracker output against the truth of its frame (both in the camera frame).
struct FrameScore {
  std::vector<double> node_err;  ///< |estimate_j - truth_j| per node [m]; empty when lost
  double mean_err = kNaN;        ///< [m]
  double max_err = kNaN;         ///< [m]
  double polyline = kNaN;        ///< bidirectional point-to-polyline distance [m]
  int swaps = 0;                 ///< see topology_swaps
  int misassigned = 0;           ///< see misassigned_nodes
  /// The tracker cannot know which end is the base: node order is matched to the truth
  /// end to end, and this says the estimate was read back to front.
  bool reversed = false;
};

/// Scores `estimate` against `truth` (same node count). An empty estimate (a lost frame)
/// gives NaN errors. Throws std::invalid_argument when the counts differ otherwise.
[[nodiscard]] FrameScore score_frame(const Nodes& estimate, const Nodes& truth);

/// The paper's SDF metric (Eq. 16, linksight::sdf_error) of `nodes` over the points of
/// `cloud` a tracker keeps (finite, within kMaxCoordinate) [m]: what a built-in mode
/// reports as FrameResult::sdf_error, for nodes from elsewhere.
[[nodiscard]] double cloud_sdf_error(const Cloud& cloud, const Nodes& nodes,
                                     const ComponentGeometry& geometry);

/// What an episode's scoring counts as an event, and as recovered.
struct ScoreParams {
  double recovered_below = 0.005;  ///< mean node error that counts as tracking [m]
  double occlusion_from = 0.2;     ///< link occluded fraction that starts an occlusion event
  /// Largest true node displacement between consecutive frames that starts a fast-motion
  /// event [m]; about half the component pitch, where SOM association starts to break.
  double fast_motion_from = 0.02;
  void validate() const;  ///< throws std::invalid_argument naming the field
};

/// A run of frames [start, end) with occlusion or fast motion, and how long the tracker
/// took afterwards to get back under ScoreParams::recovered_below.
struct Event {
  enum class Kind { occlusion, fast_motion };
  Kind kind = Kind::occlusion;
  int start = 0, end = 0;      ///< frames [start, end)
  int frames_to_recover = -1;  ///< from `end` until the error is back under; -1: never
};
[[nodiscard]] const char* to_string(Event::Kind kind);

/// Mean, median, 95th percentile (linksight::quantile) and maximum of the finite values
/// of a sample; NaN when there are none.
struct Stats {
  double mean = kNaN, median = kNaN, p95 = kNaN, max = kNaN;
  [[nodiscard]] static Stats of(std::vector<double> values);
};

struct EpisodeSummary {
  int frames = 0;
  int lost_frames = 0;
  Stats node_err;             ///< of the per-frame mean node error over tracked frames [m]
  double under_2mm = 0;       ///< fraction of all frames with mean error < 2 mm
  double under_5mm = 0;       ///< fraction of all frames with mean error < 5 mm
  double mean_sdf = kNaN;     ///< mean of the paper's SDF metric (Eq. 16) [m]
  double mean_polyline = kNaN;  ///< mean bidirectional point-to-polyline distance [m]
  int reinit_count = 0;       ///< frames where LSQ re-initialization fired
  int swaps = 0;              ///< sum of topology swaps over frames
  int swap_frames = 0;        ///< frames with at least one swap
  int misassigned = 0;        ///< sum of misassigned nodes over frames
  Stats time;                 ///< tracker time per frame [s] (each kept as a float)
  std::vector<Event> events;
  double occluded_fraction_mean = kNaN;  ///< of the link, over all frames
  double occluded_fraction_max = 0;      ///< of the link, over all frames
  long non_finite_nodes = 0;             ///< output nodes with a NaN or inf coordinate, summed
};

/// One number of an episode's summary, as `run` (summary.json) and `sweep` (the cell
/// tables) both report it: one name (units in it: `_mm`, `pct_`), one value.
struct EpisodeMetric {
  const char* name;
  double value;  ///< NaN: not defined (no tracked frame, no recovered event)
  bool integer;  ///< a count
};

/// The deterministic metrics of `s`, in their column order: frames, lost_frames,
/// node_err_{mean,median,p95,max}_mm, pct_frames_under_{2,5}mm, sdf_err_mean_mm,
/// polyline_err_mean_mm, swaps, swap_frames, misassigned_nodes, reinit_count,
/// occluded_fraction_{mean,max}, events, events_recovered, recover_frames_max,
/// non_finite_nodes. (Timing is not among them: it differs run to run.)
[[nodiscard]] std::vector<EpisodeMetric> episode_metrics(const EpisodeSummary& s);

/// Accumulates an episode frame by frame: counts, sums and events as the frames come, and
/// of each frame only what the exact quantiles need, its mean node error (8 bytes) and its
/// time (4), so a long episode costs 12 bytes a frame.
class EpisodeScorer {
 public:
  explicit EpisodeScorer(const ScoreParams& params = {});  ///< validates params
  /// One frame: its score, the tracker's SDF metric, re-initialization flag and time,
  /// the link's occluded fraction and the largest true node displacement since the
  /// previous frame [m], and how many output nodes were not finite.
  void add(const FrameScore& score, double sdf, bool reinit, double time_s,
           double occluded_fraction, double truth_motion, long non_finite_nodes = 0);
  /// Over the frames added so far (an event still running ends at the last of them).
  [[nodiscard]] EpisodeSummary summary() const;

 private:
  ScoreParams params_;
  EpisodeSummary sums_;  // counts and maxima; the sums and quantiles below
  std::vector<double> err_;  // tracked frames' mean node error, in frame order
  std::vector<float> time_;  // every frame's tracker time [s]: a wall clock's, never exact
  double occluded_sum_ = 0, sdf_sum_ = 0, poly_sum_ = 0;
  int n_sdf_ = 0, n_poly_ = 0;
  // Per Event::Kind: the ended runs in start order, and the start of the one running
  // (-1: none).
  std::vector<Event> events_[2];
  int run_start_[2] = {-1, -1};
  // Ended runs not yet recovered from (kind, index in events_): the first frame under
  // recovered_below recovers them all.
  std::vector<std::pair<int, std::size_t>> pending_;
};

}  // namespace linksight::sim
