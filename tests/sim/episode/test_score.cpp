// Scoring: node errors, TrackDLO's polyline distance, topology swaps, episode statistics
// and events, on small hand-made cases with known answers.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

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
