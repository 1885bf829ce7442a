#include "linksight/sim/score.hpp"

#include "linksight/tracker/backend.hpp"
#include "linksight/tracker/sdf.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <string>

#include "linksight/tracker/quantile.hpp"

namespace linksight::sim {

double point_to_polyline(const Eigen::Vector3d& p, const Nodes& nodes) {
  if (nodes.empty()) return kNaN;
  double best = (p - nodes.front()).norm();
  for (std::size_t j = 0; j + 1 < nodes.size(); ++j) {
    const Eigen::Vector3d a = nodes[j], ab = nodes[j + 1] - a;
    const double len2 = ab.squaredNorm();
    const double s = len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
    best = std::min(best, (p - (a + s * ab)).norm());
  }
  return best;
}

double bidirectional_polyline_distance(const Nodes& a, const Nodes& b) {
  if (a.empty() || b.empty()) return kNaN;
  double ab = 0, ba = 0;
  for (const auto& p : a) ab += point_to_polyline(p, b);
  for (const auto& p : b) ba += point_to_polyline(p, a);
  return 0.5 * (ab / static_cast<double>(a.size()) + ba / static_cast<double>(b.size()));
}

namespace {
// For each estimated ball node, the index of its nearest true ball. The tip (last node)
// has no ball under it: the SOM places it on the last ball's far cap, nearer true ball
// M-1 than the true tip, which is neither a change of order nor a wrong ball.
std::vector<std::size_t> nearest_balls(const Nodes& estimate, const Nodes& truth) {
  if (estimate.empty() || truth.empty()) return {};
  const std::size_t balls = std::min(estimate.size(), truth.size()) - 1;
  std::vector<std::size_t> nearest(balls, 0);
  for (std::size_t j = 0; j < balls; ++j)
    for (std::size_t k = 1; k < balls; ++k)
      if ((estimate[j] - truth[k]).squaredNorm() <
          (estimate[j] - truth[nearest[j]]).squaredNorm())
        nearest[j] = k;
  return nearest;
}

// The event of `kind` (0: occlusion, 1: fast motion) over frames [start, end).
Event event_of(int kind, int start, int end) {
  Event e;
  e.kind = kind == 0 ? Event::Kind::occlusion : Event::Kind::fast_motion;
  e.start = start;
  e.end = end;
  return e;
}
}  // namespace

int topology_swaps(const Nodes& estimate, const Nodes& truth) {
  const std::vector<std::size_t> nearest = nearest_balls(estimate, truth);
  int swaps = 0;
  for (std::size_t j = 0; j < nearest.size(); ++j)
    for (std::size_t k = j + 1; k < nearest.size(); ++k) swaps += nearest[j] > nearest[k];
  return swaps;
}

int misassigned_nodes(const Nodes& estimate, const Nodes& truth) {
  const std::vector<std::size_t> nearest = nearest_balls(estimate, truth);
  int n = 0;
  for (std::size_t j = 0; j < nearest.size(); ++j) n += nearest[j] != j;
  return n;
}

FrameScore score_frame(const Nodes& estimate, const Nodes& truth) {
  FrameScore s;
  if (estimate.empty()) return s;
  if (estimate.size() != truth.size())
    throw std::invalid_argument("score: " + std::to_string(estimate.size()) +
                                " estimated nodes for " + std::to_string(truth.size()) +
                                " true nodes");
  auto mean_err = [&](bool reversed) {
    double sum = 0;
    for (std::size_t j = 0; j < truth.size(); ++j)
      sum += (estimate[reversed ? truth.size() - 1 - j : j] - truth[j]).norm();
    return sum;
  };
  s.reversed = mean_err(true) < mean_err(false);
  Nodes e = estimate;
  if (s.reversed) std::reverse(e.begin(), e.end());
  s.node_err.resize(e.size());
  for (std::size_t j = 0; j < e.size(); ++j) s.node_err[j] = (e[j] - truth[j]).norm();
  s.mean_err = std::accumulate(s.node_err.begin(), s.node_err.end(), 0.0) /
               static_cast<double>(e.size());
  s.max_err = *std::max_element(s.node_err.begin(), s.node_err.end());
  s.polyline = bidirectional_polyline_distance(e, truth);
  s.swaps = topology_swaps(e, truth);
  s.misassigned = misassigned_nodes(e, truth);
  return s;
}

void ScoreParams::validate() const {
  auto check = [](bool ok, const char* name, double v, const char* rule) {
    if (!ok)
      throw std::invalid_argument(std::string("score ") + name + " = " + std::to_string(v) +
                                  ": " + rule);
  };
  check(recovered_below > 0 && std::isfinite(recovered_below), "recovered_below",
        recovered_below, "must be > 0 m");
  check(occlusion_from > 0 && occlusion_from <= 1, "occlusion_from", occlusion_from,
        "must be in (0, 1]");
  check(fast_motion_from > 0 && std::isfinite(fast_motion_from), "fast_motion_from",
        fast_motion_from, "must be > 0 m");
}

const char* to_string(Event::Kind kind) {
  return kind == Event::Kind::occlusion ? "occlusion" : "fast_motion";
}

Stats Stats::of(std::vector<double> v) {
  Stats s;
  std::erase_if(v, [](double x) { return !std::isfinite(x); });
  if (v.empty()) return s;
  std::sort(v.begin(), v.end());  // the mean sums in ascending order
  s.mean = std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
  s.median = quantile_in_place(v, 0.5);
  s.p95 = quantile_in_place(v, 0.95);
  s.max = v.back();
  return s;
}

EpisodeScorer::EpisodeScorer(const ScoreParams& params) : params_(params) { params.validate(); }

void EpisodeScorer::add(const FrameScore& score, double sdf, bool reinit, double time_s,
                        double occluded_fraction, double truth_motion, long non_finite_nodes) {
  EpisodeSummary& s = sums_;
  const int f = s.frames++;
  time_.push_back(static_cast<float>(time_s));
  s.reinit_count += reinit;
  occluded_sum_ += occluded_fraction;
  s.occluded_fraction_max = std::max(s.occluded_fraction_max, occluded_fraction);
  s.non_finite_nodes += non_finite_nodes;
  // Events: maximal runs of flagged frames, each kind on its own; a run ends at the first
  // frame without its flag, which is the first that may recover from it.
  const bool flagged[2] = {occluded_fraction >= params_.occlusion_from,
                           truth_motion >= params_.fast_motion_from};
  for (int kind = 0; kind < 2; ++kind) {
    if (flagged[kind]) {
      if (run_start_[kind] < 0) run_start_[kind] = f;
    } else if (run_start_[kind] >= 0) {
      events_[kind].push_back(event_of(kind, run_start_[kind], f));
      pending_.emplace_back(kind, events_[kind].size() - 1);
      run_start_[kind] = -1;
    }
  }
  if (score.mean_err < params_.recovered_below) {  // NaN (lost) is not recovered
    for (const auto& [kind, i] : pending_) {
      Event& e = events_[kind][i];
      e.frames_to_recover = f - e.end;
    }
    pending_.clear();
  }
  if (!std::isfinite(score.mean_err)) {
    ++s.lost_frames;
    return;
  }
  err_.push_back(score.mean_err);
  s.under_2mm += score.mean_err < 0.002;
  s.under_5mm += score.mean_err < 0.005;
  s.swaps += score.swaps;
  s.swap_frames += score.swaps > 0;
  s.misassigned += score.misassigned;
  if (std::isfinite(sdf)) sdf_sum_ += sdf, ++n_sdf_;
  if (std::isfinite(score.polyline)) poly_sum_ += score.polyline, ++n_poly_;
}

EpisodeSummary EpisodeScorer::summary() const {
  EpisodeSummary s = sums_;
  if (s.frames > 0) {
    s.under_2mm /= s.frames;
    s.under_5mm /= s.frames;
    s.occluded_fraction_mean = occluded_sum_ / s.frames;
  }
  if (n_sdf_) s.mean_sdf = sdf_sum_ / n_sdf_;
  if (n_poly_) s.mean_polyline = poly_sum_ / n_poly_;
  s.node_err = Stats::of(err_);
  s.time = Stats::of(std::vector<double>(time_.begin(), time_.end()));
  for (int kind = 0; kind < 2; ++kind) {
    s.events.insert(s.events.end(), events_[kind].begin(), events_[kind].end());
    if (run_start_[kind] >= 0) {  // still running at the last frame: not recovered
      s.events.push_back(event_of(kind, run_start_[kind], s.frames));
    }
  }
  std::stable_sort(s.events.begin(), s.events.end(),
                   [](const Event& a, const Event& b) { return a.start < b.start; });
  return s;
}

std::vector<EpisodeMetric> episode_metrics(const EpisodeSummary& s) {
  int recovered = 0, recover_max = -1;
  for (const Event& e : s.events) {
    if (e.frames_to_recover < 0) continue;
    ++recovered;
    recover_max = std::max(recover_max, e.frames_to_recover);
  }
  constexpr double mm = 1e3;  // reports in millimetres
  return {{"frames", static_cast<double>(s.frames), true},
          {"lost_frames", static_cast<double>(s.lost_frames), true},
          {"node_err_mean_mm", s.node_err.mean * mm, false},
          {"node_err_median_mm", s.node_err.median * mm, false},
          {"node_err_p95_mm", s.node_err.p95 * mm, false},
          {"node_err_max_mm", s.node_err.max * mm, false},
          {"pct_frames_under_2mm", 100 * s.under_2mm, false},
          {"pct_frames_under_5mm", 100 * s.under_5mm, false},
          {"sdf_err_mean_mm", s.mean_sdf * mm, false},
          {"polyline_err_mean_mm", s.mean_polyline * mm, false},
          {"swaps", static_cast<double>(s.swaps), true},
          {"swap_frames", static_cast<double>(s.swap_frames), true},
          {"misassigned_nodes", static_cast<double>(s.misassigned), true},
          {"reinit_count", static_cast<double>(s.reinit_count), true},
          {"occluded_fraction_mean", s.occluded_fraction_mean, false},
          {"occluded_fraction_max", s.occluded_fraction_max, false},
          {"events", static_cast<double>(s.events.size()), true},
          {"events_recovered", static_cast<double>(recovered), true},
          {"recover_frames_max", recover_max < 0 ? kNaN : static_cast<double>(recover_max), true},
          {"non_finite_nodes", static_cast<double>(s.non_finite_nodes), true}};
}

double cloud_sdf_error(const Cloud& cloud, const Nodes& nodes, const ComponentGeometry& geometry) {
  std::vector<float> x, y, z;
  x.reserve(cloud.size());
  y.reserve(cloud.size());
  z.reserve(cloud.size());
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const float px = cloud.xyz[3 * i], py = cloud.xyz[3 * i + 1], pz = cloud.xyz[3 * i + 2];
    if (check_point(px, py, pz) != PointCheck::kept) continue;
    x.push_back(px);
    y.push_back(py);
    z.push_back(pz);
  }
  return sdf_error(PointsView{x, y, z}, nodes, geometry);
}

}  // namespace linksight::sim
