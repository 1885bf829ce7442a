// Scoring: node errors, TrackDLO's polyline distance, topology swaps, episode statistics
// and events, on small hand-made cases with known answers.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include "linksight/sim/score.hpp"

namespace linksight::sim {
namespace {

constexpr double kTol = 1e-12;

Nodes line(int n, double pitch, const Eigen::Vector3d& shift = Eigen::Vector3d::Zero()) {
  Nodes nodes;
  for (int j = 0; j < n; ++j) nodes.push_back(Eigen::Vector3d(j * pitch, 0, 0) + shift);
  return nodes;
}

TEST(Score, PointToPolylineUsesSegmentsAndEnds) {
  const Nodes l = line(3, 1.0);  // (0,0,0) - (1,0,0) - (2,0,0)
  EXPECT_NEAR(point_to_polyline({0.5, 2.0, 0.0}, l), 2.0, kTol);   // above a segment
  EXPECT_NEAR(point_to_polyline({-3.0, 4.0, 0.0}, l), 5.0, kTol);  // beyond the first end
  EXPECT_NEAR(point_to_polyline({1.0, 0.0, 0.0}, l), 0.0, kTol);
}

TEST(Score, BidirectionalDistanceOfAShiftedCopyIsTheShift) {
  const Nodes a = line(12, 0.045);
  EXPECT_NEAR(bidirectional_polyline_distance(a, a), 0.0, kTol);
  EXPECT_NEAR(bidirectional_polyline_distance(a, line(12, 0.045, {0, 0.003, 0.004})), 0.005, kTol);
  // Nodes slid along the same line: zero, unlike the node error.
  const Nodes slid = line(12, 0.045, {0.01, 0, 0});
  EXPECT_GT(bidirectional_polyline_distance(a, slid), 0.0);  // the ends overhang
  EXPECT_LT(bidirectional_polyline_distance(a, slid), 0.002);
}

TEST(Score, SwapsCountOrderInversionsAndMisassignedNodesWrongBalls) {
  const Nodes truth = line(12, 0.045);
  EXPECT_EQ(topology_swaps(truth, truth), 0);
  EXPECT_EQ(misassigned_nodes(truth, truth), 0);
  Nodes e = truth;
  std::swap(e[3], e[4]);  // neighbours trade places: one inversion, two wrong balls
  EXPECT_EQ(topology_swaps(e, truth), 1);
  EXPECT_EQ(misassigned_nodes(e, truth), 2);
  e = truth;
  e[7] = truth[2];  // node 7 jumps back over nodes 3..6: four inversions (and 2 = 2)
  EXPECT_EQ(topology_swaps(e, truth), 4);
  EXPECT_EQ(misassigned_nodes(e, truth), 1);
  e = truth;
  e[5] = truth[4] + Eigen::Vector3d(0.01, 0, 0);  // a hidden ball's node on its neighbour
  EXPECT_EQ(topology_swaps(e, truth), 0);
  EXPECT_EQ(misassigned_nodes(e, truth), 1);
  e = truth;
  std::reverse(e.begin(), e.begin() + 11);  // the balls read back to front: all pairs
  EXPECT_EQ(topology_swaps(e, truth), 11 * 10 / 2);
  // The tip is not a ball: an estimated tip on the last ball is no swap, and no estimated
  // ball node counts as a swap for being nearest the true tip...
  e = truth;
  e[11] = truth[10] + Eigen::Vector3d(0.02, 0.0, 0.0);
  EXPECT_EQ(topology_swaps(e, truth), 0);
  e[11] = truth[10];
  EXPECT_EQ(topology_swaps(e, truth), 0);
  e = truth;
  e[9] = truth[11] - Eigen::Vector3d(0.001, 0, 0);  // nearest the true tip: not a candidate
  EXPECT_EQ(topology_swaps(e, truth), 0);
  EXPECT_EQ(misassigned_nodes(e, truth), 1);  // nearest true ball: 10
  EXPECT_EQ(topology_swaps({}, truth), 0);
  EXPECT_EQ(misassigned_nodes(truth, {}), 0);
  // ...but a ball node beyond the next ball's node still is.
  e[9] = truth[10] + Eigen::Vector3d(0.005, 0, 0);
  e[10] = truth[9];
  EXPECT_EQ(topology_swaps(e, truth), 1);
  EXPECT_EQ(misassigned_nodes(e, truth), 2);
}

TEST(Score, FrameScoreMatchesEndsAndReportsErrors) {
  const Nodes truth = line(12, 0.045);
  Nodes e = line(12, 0.045, {0, 0, 0.002});
  FrameScore s = score_frame(e, truth);
  EXPECT_FALSE(s.reversed);
  EXPECT_NEAR(s.mean_err, 0.002, kTol);
  EXPECT_NEAR(s.max_err, 0.002, kTol);
  EXPECT_EQ(s.swaps, 0);
  e[5].z() += 0.010;  // one node 12 mm off
  s = score_frame(e, truth);
  EXPECT_NEAR(s.max_err, 0.012, kTol);
  EXPECT_NEAR(s.node_err[5], 0.012, kTol);
  EXPECT_NEAR(s.mean_err, (11 * 0.002 + 0.012) / 12, kTol);
  // The same estimate read back to front scores the same.
  std::reverse(e.begin(), e.end());
  const FrameScore r = score_frame(e, truth);
  EXPECT_TRUE(r.reversed);
  EXPECT_NEAR(r.mean_err, s.mean_err, kTol);
  EXPECT_NEAR(r.node_err[5], 0.012, kTol);
  // Lost: NaN, not zero.
  EXPECT_TRUE(std::isnan(score_frame({}, truth).mean_err));
  EXPECT_THROW((void)score_frame(line(11, 0.045), truth), std::invalid_argument);
}

TEST(Score, StatsOfASample) {
  std::vector<double> v;
  for (int i = 1; i <= 20; ++i) v.push_back(i);
  v.push_back(std::nan(""));  // ignored
  const Stats s = Stats::of(v);
  EXPECT_DOUBLE_EQ(s.mean, 10.5);
  EXPECT_DOUBLE_EQ(s.median, 10.5);
  EXPECT_DOUBLE_EQ(s.p95, 19.05);  // linksight::quantile: h = 0.95 * 19, 19 + 0.05 * (20 - 19)
  EXPECT_DOUBLE_EQ(s.max, 20.0);
  EXPECT_TRUE(std::isnan(Stats::of({}).mean));
}

// Ten frames: good, an occlusion over frames 3-4 with large errors, recovery two frames
// later; a fast-motion frame 8 that is never recovered from; a lost frame 9.
TEST(Score, EpisodeEventsAndRecovery) {
  EpisodeScorer scorer;
  const double err_mm[] = {1, 1.5, 3, 20, 30, 8, 6, 4, 9, NAN};
  const double occluded[] = {0, 0, 0, 0.5, 0.4, 0.1, 0, 0, 0, 0};
  const double motion_m[] = {0, 0.001, 0.001, 0.001, 0.001, 0.001, 0.001, 0.001, 0.05, 0.001};
  for (int f = 0; f < 10; ++f) {
    FrameScore s;
    s.mean_err = err_mm[f] * 1e-3;
    s.swaps = f == 4 ? 2 : 0;
    s.misassigned = f == 3 || f == 4 ? 3 : 0;
    scorer.add(s, 0.001, f == 5, 1e-3 * (f + 1), occluded[f], motion_m[f]);
  }
  const EpisodeSummary sum = scorer.summary();
  EXPECT_EQ(sum.frames, 10);
  EXPECT_EQ(sum.lost_frames, 1);
  EXPECT_EQ(sum.reinit_count, 1);
  EXPECT_EQ(sum.swaps, 2);
  EXPECT_EQ(sum.swap_frames, 1);
  EXPECT_EQ(sum.misassigned, 6);
  EXPECT_DOUBLE_EQ(sum.under_2mm, 0.2);  // of all 10 frames
  EXPECT_DOUBLE_EQ(sum.under_5mm, 0.4);
  EXPECT_NEAR(sum.node_err.max, 0.030, kTol);
  EXPECT_NEAR(sum.node_err.median, 0.006, kTol);
  // Times are kept as float (a wall clock's, 12 bytes a frame with the error's double).
  EXPECT_FLOAT_EQ(static_cast<float>(sum.time.max), 0.010f);
  ASSERT_EQ(sum.events.size(), 2u);
  EXPECT_EQ(sum.events[0].kind, Event::Kind::occlusion);
  EXPECT_EQ(sum.events[0].start, 3);
  EXPECT_EQ(sum.events[0].end, 5);
  EXPECT_EQ(sum.events[0].frames_to_recover, 2);  // frame 7 is under 5 mm
  EXPECT_EQ(sum.events[1].kind, Event::Kind::fast_motion);
  EXPECT_EQ(sum.events[1].start, 8);
  EXPECT_EQ(sum.events[1].frames_to_recover, -1);  // frame 9 is lost
}

// A summary before the last frame: an event still running ends at the frames so far,
// unrecovered; the scorer goes on, and the event then ends and recovers as it would have.
TEST(Score, SummaryMidEpisodeEndsTheRunningEventThere) {
  EpisodeScorer scorer;
  const auto add = [&](double err_mm, double occluded) {
    FrameScore s;
    s.mean_err = err_mm * 1e-3;
    scorer.add(s, 0.001, false, 1e-3, occluded, 0);
  };
  add(1, 0);
  add(20, 0.5);
  add(30, 0.5);
  EpisodeSummary mid = scorer.summary();
  ASSERT_EQ(mid.events.size(), 1u);
  EXPECT_EQ(mid.events[0].start, 1);
  EXPECT_EQ(mid.events[0].end, 3);
  EXPECT_EQ(mid.events[0].frames_to_recover, -1);
  add(9, 0);  // the board is gone, the error not yet back
  add(2, 0);
  const EpisodeSummary end = scorer.summary();
  ASSERT_EQ(end.events.size(), 1u);
  EXPECT_EQ(end.events[0].end, 3);
  EXPECT_EQ(end.events[0].frames_to_recover, 1);
  EXPECT_EQ(end.frames, 5);
  EXPECT_NEAR(end.node_err.max, 0.030, kTol);
}

// The scorer as it was before it streamed (it kept every frame's row and read them at the
// end): the reference the streaming one must reproduce.
struct BatchScorer {
  struct Row {
    double mean_err, sdf, polyline, time_s, occluded_fraction;
    int swaps, misassigned;
    long non_finite;
    bool reinit, occluded, fast;
  };
  ScoreParams params;
  std::vector<Row> rows;
  void add(const FrameScore& score, double sdf, bool reinit, double time_s, double occluded,
           double motion, long non_finite) {
    rows.push_back({score.mean_err, sdf, score.polyline, time_s, occluded, score.swaps,
                    score.misassigned, non_finite, reinit, occluded >= params.occlusion_from,
                    motion >= params.fast_motion_from});
  }
  EpisodeSummary summary() const {
    EpisodeSummary s;
    s.frames = static_cast<int>(rows.size());
    std::vector<double> err, time;
    double sdf = 0, poly = 0, occluded_sum = 0;
    int n_sdf = 0, n_poly = 0;
    for (const Row& r : rows) {
      time.push_back(r.time_s);
      s.reinit_count += r.reinit;
      occluded_sum += r.occluded_fraction;
      s.occluded_fraction_max = std::max(s.occluded_fraction_max, r.occluded_fraction);
      s.non_finite_nodes += r.non_finite;
      if (!std::isfinite(r.mean_err)) {
        ++s.lost_frames;
        continue;
      }
      err.push_back(r.mean_err);
      s.under_2mm += r.mean_err < 0.002;
      s.under_5mm += r.mean_err < 0.005;
      s.swaps += r.swaps;
      s.swap_frames += r.swaps > 0;
      s.misassigned += r.misassigned;
      if (std::isfinite(r.sdf)) sdf += r.sdf, ++n_sdf;
      if (std::isfinite(r.polyline)) poly += r.polyline, ++n_poly;
    }
    if (s.frames > 0) {
      s.under_2mm /= s.frames;
      s.under_5mm /= s.frames;
      s.occluded_fraction_mean = occluded_sum / s.frames;
    }
    if (n_sdf) s.mean_sdf = sdf / n_sdf;
    if (n_poly) s.mean_polyline = poly / n_poly;
    s.node_err = Stats::of(err);
    s.time = Stats::of(time);
    for (const Event::Kind kind : {Event::Kind::occlusion, Event::Kind::fast_motion}) {
      auto flagged = [&](int f) { return kind == Event::Kind::occlusion ? rows[f].occluded : rows[f].fast; };
      for (int f = 0; f < s.frames;) {
        if (!flagged(f)) {
          ++f;
          continue;
        }
        Event e;
        e.kind = kind;
        e.start = f;
        while (f < s.frames && flagged(f)) ++f;
        e.end = f;
        for (int g = e.end; g < s.frames; ++g)
          if (rows[g].mean_err < params.recovered_below) {
            e.frames_to_recover = g - e.end;
            break;
          }
        s.events.push_back(e);
      }
    }
    std::stable_sort(s.events.begin(), s.events.end(),
                     [](const Event& a, const Event& b) { return a.start < b.start; });
    return s;
  }
};

// Bit for bit (NaN for NaN) where both are NaN.
void expect_same(double a, double b, const char* what) {
  if (std::isnan(a) && std::isnan(b)) return;
  EXPECT_EQ(a, b) << what;
}

// The streaming scorer gives the batch scorer's summary, every field bit for bit, after
// every frame of seeded random episodes: lost frames, overlapping occlusion and
// fast-motion runs, runs still going at the end, recoveries on the frame a run ends.
TEST(Score, StreamingEqualsTheBatchScorerAfterEveryFrame) {
  std::mt19937_64 rng(12);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int episode = 0; episode < 20; ++episode) {
    EpisodeScorer streaming;
    BatchScorer batch;
    const int frames = 1 + static_cast<int>(u(rng) * 150);
    for (int f = 0; f < frames; ++f) {
      FrameScore sc;
      const double x = u(rng);
      sc.mean_err = x < 0.1 ? std::nan("") : 0.012 * u(rng);
      sc.polyline = u(rng) < 0.1 ? std::nan("") : 0.01 * u(rng);
      sc.swaps = u(rng) < 0.1 ? 1 + static_cast<int>(3 * u(rng)) : 0;
      sc.misassigned = u(rng) < 0.1 ? 2 : 0;
      const double sdf = u(rng) < 0.1 ? std::nan("") : 0.002 * u(rng);
      const bool reinit = u(rng) < 0.05;
      const double time = std::floor(u(rng) * 4096) / 1024.0;  // exact in a float
      const double occluded = u(rng) < 0.3 ? 0.2 + 0.5 * u(rng) : 0.2 * u(rng);
      const double motion = u(rng) < 0.2 ? 0.02 + 0.02 * u(rng) : 0.02 * u(rng);
      const long non_finite = u(rng) < 0.05 ? 1 : 0;
      streaming.add(sc, sdf, reinit, time, occluded, motion, non_finite);
      batch.add(sc, sdf, reinit, time, occluded, motion, non_finite);
      const EpisodeSummary a = streaming.summary(), b = batch.summary();
      SCOPED_TRACE("episode " + std::to_string(episode) + ", frame " + std::to_string(f));
      EXPECT_EQ(a.frames, b.frames);
      EXPECT_EQ(a.lost_frames, b.lost_frames);
      EXPECT_EQ(a.reinit_count, b.reinit_count);
      EXPECT_EQ(a.swaps, b.swaps);
      EXPECT_EQ(a.swap_frames, b.swap_frames);
      EXPECT_EQ(a.misassigned, b.misassigned);
      EXPECT_EQ(a.non_finite_nodes, b.non_finite_nodes);
      for (const auto& [x1, x2, what] :
           {std::tuple{a.under_2mm, b.under_2mm, "under_2mm"},
            std::tuple{a.under_5mm, b.under_5mm, "under_5mm"},
            std::tuple{a.mean_sdf, b.mean_sdf, "mean_sdf"},
            std::tuple{a.mean_polyline, b.mean_polyline, "mean_polyline"},
            std::tuple{a.occluded_fraction_mean, b.occluded_fraction_mean, "occluded mean"},
            std::tuple{a.occluded_fraction_max, b.occluded_fraction_max, "occluded max"},
            std::tuple{a.node_err.mean, b.node_err.mean, "err mean"},
            std::tuple{a.node_err.median, b.node_err.median, "err median"},
            std::tuple{a.node_err.p95, b.node_err.p95, "err p95"},
            std::tuple{a.node_err.max, b.node_err.max, "err max"},
            std::tuple{a.time.mean, b.time.mean, "time mean"},
            std::tuple{a.time.p95, b.time.p95, "time p95"},
            std::tuple{a.time.max, b.time.max, "time max"}})
        expect_same(x1, x2, what);
      ASSERT_EQ(a.events.size(), b.events.size());
      for (std::size_t k = 0; k < a.events.size(); ++k) {
        EXPECT_EQ(a.events[k].kind, b.events[k].kind) << k;
        EXPECT_EQ(a.events[k].start, b.events[k].start) << k;
        EXPECT_EQ(a.events[k].end, b.events[k].end) << k;
        EXPECT_EQ(a.events[k].frames_to_recover, b.events[k].frames_to_recover) << k;
      }
      if (HasFailure()) return;
    }
  }
}

TEST(Score, BadParametersAreNamed) {
  ScoreParams p;
  p.occlusion_from = 0;
  try {
    p.validate();
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("occlusion_from"), std::string::npos) << e.what();
  }
  p = {};
  p.recovered_below = -1;
  EXPECT_THROW(EpisodeScorer{p}, std::invalid_argument);
}

}  // namespace
}  // namespace linksight::sim
