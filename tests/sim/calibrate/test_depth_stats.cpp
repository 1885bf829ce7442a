// Depth-camera statistics (sim/depth_stats) and the noise-model fit behind
// `calibrate-noise`: recovered from simulated recordings whose parameters are known, and
// measured on the real SR305 frames against the figures measured independently on frames
// of this kind (issue 8); bad input is named.
#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <limits>
#include <numbers>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "linksight/io/frames.hpp"
#include "linksight/sim/depth_stats.hpp"
#include "linksight/sim/episode.hpp"
#include "linksight/sim/mesh.hpp"
#include "linksight/sim/sensor.hpp"
#include "linksight/sim/sensor_noise.hpp"
#include "linksight/sim/scene.hpp"
#include "test_support.hpp"

#include <gtest/gtest-spi.h>

namespace linksight::sim {
namespace {

// Issue 8: sigma within 10%, the baseline within 10%, the projector side exactly.
constexpr double kSigmaRelTol = 0.10;
constexpr double kBaselineRelTol = 0.10;
// The correlation width: as sigma (the issue does not name it; it is the sigma of a kernel).
constexpr double kCorrelationRelTol = 0.10;

const std::filesystem::path kReal = std::filesystem::path(LINKSIGHT_TEST_DATA_DIR) / "sr305-hand";

// A wall 0.95 m away and three boxes at 0.45-0.75 m: flat surfaces at several depths and
// vertical edges whose projector shadows fall on the wall; the link is out of view (its
// balls' rims would add intermediate depths). Noise terms as given, k_theta 1e-4 m^1.5
// unless `more` sets it.
std::vector<io::DepthImage> render(const std::string& name, double a, double c, double baseline,
                                   double correlation_px, int frames, io::Intrinsics& K,
                                   const std::vector<std::string>& more = {}) {
  const auto dir = test::scratch_dir(name);
  std::ofstream(dir / "scene.yaml") << R"(duration_s: 1.0
seed: 5
camera:
  preset: sr300
  look_at: {eye_m: [0.0, -0.7, 0.5], target_m: [0.0, 0.0, 0.5], up: [0, 0, 1]}
noise:
  preset: sr300-one-field  # the model the one-field fit recovers
segmentation: {mode: truth}
base: {waypoints: [{t_s: 0, position_m: [0.0, -2.0, 0.5]}]}  # the link behind the camera
background:
  wall: {position_m: [0.0, 0.25, 0.5], half_extents_m: [1.5, 0.01, 1.0]}
  objects:
    - {shape: box, half_extents_m: [0.04, 0.04, 0.12], position_m: [-0.25, -0.15, 0.45]}
    - {shape: box, half_extents_m: [0.03, 0.03, 0.10], position_m: [0.22, -0.25, 0.55]}
    - {shape: box, half_extents_m: [0.05, 0.05, 0.08], position_m: [-0.05, 0.05, 0.25]}
)";
  std::vector<std::string> set = {"noise.axial.a_m=" + std::to_string(a),
                                  "noise.axial.c_per_m=" + std::to_string(c),
                                  "noise.shadow.baseline_m=" + std::to_string(baseline),
                                  "noise.axial.correlation_px=" + std::to_string(correlation_px),
                                  "noise.axial.k_theta=0.0001"};
  set.insert(set.end(), more.begin(), more.end());
  const Scene scene = load_scene(dir / "scene.yaml", set);
  K = scene.camera.intrinsics;
  EpisodeOptions o;
  o.frames = frames;
  o.modes = {parse_mode("paper")};
  Episode e(scene, o);
  std::vector<io::DepthImage> out;
  while (e.done() < e.frames()) out.push_back(e.step().image->depth);
  return out;
}

struct Case {
  double a, c, baseline, correlation_px;
};

class Recovers : public ::testing::TestWithParam<Case> {};

TEST_P(Recovers, SigmaBaselineAndSideOfASimulatedRecording) {
  const Case k = GetParam();
  io::Intrinsics K;
  const std::vector<io::DepthImage> frames = render(
      "depth_stats_" + std::to_string(static_cast<int>(k.baseline * 1e3 + 100)), k.a, k.c,
      k.baseline, k.correlation_px, 8, K);
  const DepthStats s = depth_stats(frames, K);
  EXPECT_EQ(s.projector_side, k.baseline > 0 ? 1 : -1);
  EXPECT_NEAR(s.baseline, k.baseline, kBaselineRelTol * std::abs(k.baseline));
  const NoiseFit fit = fit_noise(s, NoiseParams::sr300_one_field());
  EXPECT_EQ(fit.params.shadow.baseline, s.baseline);
  // The plane fit reads sigma low by the window response of the noise's correlation.
  const double read = std::sqrt(window_response(k.correlation_px).variance_factor);
  int bins = 0;
  for (const SigmaBin& b : s.sigma_by_depth) {
    if (b.windows < 20) continue;
    ++bins;
    const double truth = k.a + k.c * b.centre * b.centre;
    SCOPED_TRACE("depth bin " + std::to_string(b.lo) + "-" + std::to_string(b.hi));
    EXPECT_NEAR(b.sigma, truth * read, kSigmaRelTol * truth * read);
    EXPECT_NEAR(fit.params.axial.sigma(b.centre, 0.0), truth, kSigmaRelTol * truth);
  }
  EXPECT_GE(bins, 3) << "the scene should give flat windows at three depths or more";
  if (k.correlation_px == 0) {
    EXPECT_LT(std::abs(s.correlation[0]), 0.1);  // white: nothing past numerical noise
    EXPECT_EQ(fit.params.axial.correlation_px, 0.0);
  } else {
    EXPECT_NEAR(fit.params.axial.correlation_px, k.correlation_px,
                kCorrelationRelTol * k.correlation_px);
  }
  EXPECT_NEAR(s.depth_step, K.depth_scale, 1e-12);
}

INSTANTIATE_TEST_SUITE_P(DepthStats, Recovers,
                         ::testing::Values(Case{0.0005, 0.0015, 0.05, 0.0},  // the sr300 preset
                                           // projector image-left, correlated noise
                                           Case{0.0003, 0.0010, -0.04, 1.5}),
                         [](const ::testing::TestParamInfo<Case>& p) {
                           return p.param.baseline > 0 ? std::string("ProjectorRight")
                                                          : std::string("ProjectorLeft");
                         });

// Issue 8: the flying-pixel and hole rates within 20%, from a recording rendered with
// chosen values. The boxes' faces are flat, so every flying pixel is the model's.
constexpr double kRateRelTol = 0.20;

TEST(DepthStats, RecoversFlyingPixelAndHoleRates) {
  struct Rates {
    double p_flying, position, spread, hole_rate, median, p90;
  };
  for (const Rates r : {Rates{0.3, 0.4, 0.2, 20, 2, 12}, Rates{0.1, 0.6, 0.1, 60, 1, 5}}) {
    SCOPED_TRACE("p_flying " + std::to_string(r.p_flying));
    io::Intrinsics K;
    const std::vector<io::DepthImage> frames = render(
        "depth_stats_rates_" + std::to_string(static_cast<int>(r.hole_rate)), 0.0005, 0.0015,
        0.05, 0.0, 8, K,
        {"noise.edges.p_flying=" + std::to_string(r.p_flying),
         "noise.edges.flying_position=" + std::to_string(r.position),
         "noise.edges.flying_spread=" + std::to_string(r.spread),
         "noise.dropouts.hole_rate=" + std::to_string(r.hole_rate),
         "noise.dropouts.hole_median_px=" + std::to_string(r.median),
         "noise.dropouts.hole_p90_px=" + std::to_string(r.p90)});
    const DepthStats s = depth_stats(frames, K);
    const NoiseFit fit = fit_noise(s, NoiseParams::sr300_one_field());
    EXPECT_NEAR(fit.params.edges.p_flying, r.p_flying, kRateRelTol * r.p_flying);
    EXPECT_NEAR(fit.params.dropouts.hole_rate, r.hole_rate, kRateRelTol * r.hole_rate);
    // Not rates (the issue sets no band for these): the position is a median of what lands
    // 10-90% across, and sizes are whole pixels of blobs that can touch and merge, so a
    // median of 2 px may read 3. Bands: 0.1 of the gap, half the median, and 30%.
    EXPECT_NEAR(fit.params.edges.flying_position, r.position, 0.1);
    EXPECT_NEAR(fit.params.dropouts.hole_median_px, r.median, 0.5 * r.median);
    EXPECT_NEAR(fit.params.dropouts.hole_p90_px, r.p90, 0.3 * r.p90);
  }
}

std::vector<io::DepthImage> real_frames(io::Intrinsics& K) {
  K = io::read_intrinsics(kReal / "intrinsics.json");
  std::vector<io::DepthImage> frames;
  for (const auto& p : io::list_frames((kReal / "frames").string()))
    frames.push_back(io::read_depth_png(p));
  return frames;
}

// edges.drop_steps from the recording: on where it reports under one pair of valid
// neighbours more than the jump apart per million (the SR305 frames: none in 1.27 million),
// off above that, kept as started under 100000 pairs; a note says which and why.
TEST(DepthStats, TheFitDropsStepsWhereTheCameraReportsNone) {
  io::Intrinsics K;
  DepthStats s = depth_stats(real_frames(K), K);
  ASSERT_GE(s.neighbour_pairs, 1000000);
  EXPECT_EQ(s.neighbour_jumps, 0);
  const auto fitted = [&](const NoiseParams& start) {
    const NoiseFit fit = fit_noise(s, start);
    std::string note;
    for (const std::string& n : fit.notes)
      if (n.rfind("edges.drop_steps", 0) == 0) note = n;
    return std::pair{fit.params.edges.drop_steps, note};
  };
  const auto [on, on_note] = fitted(NoiseParams::sr300_one_field());
  EXPECT_TRUE(on);
  EXPECT_EQ(on_note, "edges.drop_steps on: 0 of " + std::to_string(s.neighbour_pairs) +
                         " valid neighbour pairs step more than the statistics' neighbour_jump");
  s.neighbour_jumps = s.neighbour_pairs / 1000000 + 1;  // just over one per million
  const auto [off, off_note] = fitted(NoiseParams::sr300_one_field());
  EXPECT_FALSE(off);
  EXPECT_EQ(off_note.rfind("edges.drop_steps off: ", 0), 0u) << off_note;
  s.neighbour_jumps = s.neighbour_pairs / 1000000;  // just under
  EXPECT_TRUE(fitted(NoiseParams::sr300_one_field()).first);
  s.neighbour_jumps = 0;
  // The rule's threshold is edges.jump, the statistic's its neighbour_jump: another jump, or
  // the edge model off, says nothing about the rule, which is kept.
  NoiseParams start = NoiseParams::sr300_one_field();
  start.edges.jump = 0.5 * s.neighbour_jump;
  EXPECT_FALSE(fitted(start).first);
  EXPECT_EQ(fitted(start).second.rfind("edges.drop_steps kept: ", 0), 0u);
  start = NoiseParams::sr300_one_field();
  start.edges.enabled = false;
  EXPECT_FALSE(fitted(start).first);
  start = NoiseParams::sr300_one_field();
  s.neighbour_pairs = 99999;
  s.neighbour_jumps = 0;
  for (const bool kept : {false, true}) {
    start.edges.drop_steps = kept;
    const auto [value, note] = fitted(start);
    EXPECT_EQ(value, kept);
    EXPECT_EQ(note, "edges.drop_steps kept: under 100000 valid neighbour pairs");
  }
}

// The figures measured on SR305 frames of this kind, independently of this code (issue 8),
// with the tolerance of that measurement: sigma to 25%, rates and the baseline to its
// stated spread.
TEST(DepthStats, RealFramesGiveTheMeasuredFigures) {
  io::Intrinsics K;
  const std::vector<io::DepthImage> frames = real_frames(K);
  ASSERT_EQ(frames.size(), 11u);
  const DepthStats s = depth_stats(frames, K);
  auto sigma_near = [&](const std::vector<SigmaBin>& bins, double lo, double expected) {
    for (const SigmaBin& b : bins)
      if (std::abs(b.lo - lo) < 1e-3) {
        EXPECT_NEAR(b.sigma, expected, 0.25 * expected) << "bin from " << lo;
        return;
      }
    ADD_FAILURE() << "no bin from " << lo;
  };
  sigma_near(s.sigma_by_depth, 0.60, 0.0004);  // 0.4 mm at 0.55-0.65 m
  sigma_near(s.sigma_by_depth, 0.70, 0.0007);  // 0.7 mm at 0.75 m
  sigma_near(s.sigma_by_depth, 0.80, 0.0009);  // 0.9 mm at 0.85 m
  sigma_near(s.sigma_by_angle, 0.0, 0.0004);     // 0.4 mm at 0-15 deg
  sigma_near(s.sigma_by_angle, 1.0472, 0.0023);  // 2.3 mm at 60-75 deg
  // Correlated: about 0.8 at 1 px, 0.5-0.6 at 2 px, about 0 at 4 px; the fit reads it
  // as a Gaussian kernel of 1-2 px.
  const double width = fit_noise(s, NoiseParams::sr300_one_field()).params.axial.correlation_px;
  EXPECT_GT(width, 1.0);
  EXPECT_LT(width, 2.0);
  EXPECT_NEAR(s.correlation[0], 0.8, 0.1);
  EXPECT_NEAR(s.correlation[1], 0.55, 0.1);
  EXPECT_LT(std::abs(s.correlation[3]), 0.15);
  // Shadows on the image-right of foreground objects: projector image-left, 55 +- 10 mm.
  EXPECT_EQ(s.projector_side, -1);
  EXPECT_NEAR(s.baseline, -0.055, 0.010);
  // Every discontinuity has an invalid band: no valid pixel jumps straight across (under
  // 1% here); the issue measured the far side invalid at about 100% at 1 px and 72-97% at
  // 2 px, the lower ends of which are the bands.
  EXPECT_LT(s.near_left.direct, 0.01 * s.near_left.edges);
  EXPECT_GT(s.near_left.invalid_1px, 0.97);
  EXPECT_GT(s.near_right.invalid_2px, 0.72);
  // Flying pixels: 4-7% of the valid pixels next to a band, about 0.4 of the way.
  EXPECT_NEAR(s.flying_rate, 0.055, 0.025);
  EXPECT_NEAR(s.flying_position, 0.4, 0.1);
  // Holes: about 11 per frame, median 2 px, 90th percentile about 17 px.
  EXPECT_NEAR(s.holes_per_frame, 11.0, 0.3 * 11.0);
  std::vector<int> h = s.hole_sizes;
  std::sort(h.begin(), h.end());
  ASSERT_FALSE(h.empty());
  EXPECT_EQ(h[h.size() / 2], 2);
  EXPECT_NEAR(h[(h.size() - 1) * 9 / 10], 17.0, 0.3 * 17.0);
  EXPECT_NEAR(s.depth_step, 0.000125, 1e-12);
}

// Issue 8's fidelity check, for both presets (the two-scale sr300 of issue 20 and
// sr300-one-field, issue 8's re-derived sr300), in sample, on the real frames' own
// geometry (0.5-0.9 m): each frame's surface rebuilt from its depth
// (depth_surface_mesh: bands and holes filled, the camera's noise smoothed away) and
// rendered through the simulated camera at the real intrinsics (rerender_surfaces), so
// the two recordings differ in the sensor model only. Bands as the issue sets them: sigma
// per depth bin within 25% (a plane fit on skin and clothing is an upper bound, and the real sigma is
// not monotone in depth, which a + c z^2 cannot follow exactly); the edge bands (first
// and second pixel invalid, each side) and the flying-pixel rate within 30%, each preset on
// the flying rate it is fitted to (below).
constexpr double kFidelitySigmaTol = 0.25;
constexpr double kFidelityEdgeTol = 0.30;

/// Which flying-pixel rate a preset is held to.
enum class FlyingRuler {
  all_band_neighbours,  ///< DepthStats::flying_rate, issue 8's (the one-field fit's)
  beside_bands,         ///< DepthStats::flying_band_rate, issue 20's (the two-scale fit's)
};

void expect_fidelity(const DepthStats& r, const DepthStats& s, FlyingRuler flying) {
  ASSERT_EQ(r.sigma_by_depth.size(), s.sigma_by_depth.size());  // the same bin edges
  int bins = 0;
  for (std::size_t b = 0; b < r.sigma_by_depth.size(); ++b) {
    const SigmaBin& rb = r.sigma_by_depth[b];
    const SigmaBin& sb = s.sigma_by_depth[b];
    if (rb.windows < kMinBinWindows || sb.windows < kMinBinWindows) continue;
    ++bins;
    SCOPED_TRACE("depth bin " + std::to_string(rb.lo) + "-" + std::to_string(rb.hi));
    EXPECT_NEAR(sb.sigma / rb.sigma, 1.0, kFidelitySigmaTol) << rb.sigma << " real, " << sb.sigma << " sim";
  }
  EXPECT_GE(bins, 3) << "the frames cover 0.5-0.9 m";
  auto edges = [&](const char* name, const EdgeSide& re, const EdgeSide& se) {
    SCOPED_TRACE(name);
    ASSERT_GE(re.edges, 100);
    ASSERT_GE(se.edges, 100);
    EXPECT_NEAR(se.invalid_1px / re.invalid_1px, 1.0, kFidelityEdgeTol);
    EXPECT_NEAR(se.invalid_2px / re.invalid_2px, 1.0, kFidelityEdgeTol);
  };
  edges("near surface left", r.near_left, s.near_left);
  edges("near surface right", r.near_right, s.near_right);
  if (flying == FlyingRuler::all_band_neighbours)
    EXPECT_NEAR(s.flying_rate / r.flying_rate, 1.0, kFidelityEdgeTol);
  else
    EXPECT_NEAR(s.flying_band_rate / r.flying_band_rate, 1.0, kFidelityEdgeTol);
  EXPECT_EQ(s.projector_side, r.projector_side);
}

TEST(DepthStats, FidelityOfTheSr300PresetOnTheRealGeometry) {
  io::Intrinsics K;
  const std::vector<io::DepthImage> real = real_frames(K);
  const DepthStats r = depth_stats(real, K);
  for (const bool two_scale : {true, false}) {
    SCOPED_TRACE(two_scale ? "sr300" : "sr300-one-field");
    const NoiseParams preset = two_scale ? NoiseParams::sr300() : NoiseParams::sr300_one_field();
    // The model's expectation (the fit's draws, the comparison's seed), not one draw's luck:
    // one draw (seed 11, as read until then) put sr300's overall flying rate at 0.83 of the
    // camera's, 4 draws with the comparison's seed at 0.66. That rate's denominator holds
    // the valid fragments inside the bands, which the model makes more of than the camera
    // (docs/sensor.md, "Flying pixels beside the bands"); sr300 is fitted to the rate
    // beside the bands instead, which counts the same pixels on both.
    const DepthStats s = depth_stats(
        rerender_surfaces(real, K, preset, kCompareSeed, RerenderFitParams{}.draws), K, {}, &real);
    expect_fidelity(r, s, two_scale ? FlyingRuler::beside_bands : FlyingRuler::all_band_neighbours);
  }
}

// Validation that is not in-sample (issue 20, part 3): the one-field fit as
// calibrate-noise makes it (shape-corrected) on one half of the real frames, compared with
// the other half's real frames through fidelity's ruler (their surfaces re-rendered with
// the fit). Both alternate halves and both depth halves, each way round.
struct HeldOut {
  FrameHalf fit, test;
};
constexpr HeldOut kHeldOut[] = {{FrameHalf::even, FrameHalf::odd},
                                {FrameHalf::odd, FrameHalf::even},
                                {FrameHalf::near, FrameHalf::far},
                                {FrameHalf::far, FrameHalf::near}};
// The issue's band for a held-out ratio sim/real.
constexpr double kHeldOutLo = 0.8, kHeldOutHi = 1.25;

std::vector<io::DepthImage> half_of(const std::vector<io::DepthImage>& all,
                                    const io::Intrinsics& K, FrameHalf half) {
  std::vector<io::DepthImage> out;
  for (const std::size_t k : frame_half(all, K, half)) out.push_back(all[k]);
  return out;
}

struct HeldOutStats {
  DepthStats fit;          // the fit half, real (which bins it covers)
  DepthStats real, sim;    // the test half: real, and re-rendered with the fit
  std::vector<TargetSpread> spread;  // with `jackknife`: the test half's (target_jackknife)
};

// `structure`: one_field (fit_noise) or two_scale (fit_noise_rerendered).
HeldOutStats held_out(const std::vector<io::DepthImage>& all, const io::Intrinsics& K,
                      const HeldOut& h, NoiseStructure structure = NoiseStructure::one_field,
                      bool jackknife = false) {
  const std::vector<io::DepthImage> fit_frames = half_of(all, K, h.fit);
  const std::vector<io::DepthImage> test_frames = half_of(all, K, h.test);
  HeldOutStats out;
  out.fit = depth_stats(fit_frames, K);
  NoiseParams quiet = NoiseParams::off();
  quiet.quantize = true;
  const DepthStats shape = depth_stats(rerender_surfaces(fit_frames, K, quiet, 1), K);
  const NoiseParams fitted =
      structure == NoiseStructure::two_scale
          ? fit_noise_rerendered(fit_frames, K, out.fit, &shape, NoiseParams::sr300_one_field())
                .params
          : fit_noise(out.fit, NoiseParams::sr300_one_field(), &shape, structure).params;
  out.real = depth_stats(test_frames, K);
  // The model's expected statistics: as many draws as the two-scale fit reads each
  // candidate over (for either structure), and not the draws it read (kCompareSeed).
  const std::vector<io::DepthImage> sim_images =
      rerender_surfaces(test_frames, K, fitted, kCompareSeed, RerenderFitParams{}.draws);
  out.sim = depth_stats(sim_images, K, {}, &test_frames);
  if (jackknife) out.spread = target_jackknife(test_frames, sim_images, K);
  return out;
}

void expect_in_band(double sim, double real, const std::string& what) {
  ASSERT_GT(real, 0) << what;
  EXPECT_GE(sim / real, kHeldOutLo) << what << ": sim " << sim << ", real " << real;
  EXPECT_LE(sim / real, kHeldOutHi) << what << ": sim " << sim << ", real " << real;
}

// Each sigma bin that the fit half and the test half (real) hold 10 windows of; the
// re-rendered test half must hold kMinSimWindows (target_mismatch's rule). A depth the fit half does not reach is an extrapolation of a + c z^2, not a
// check of the fit: the near half reaches 0.8-0.9 m with too few windows, and the far half
// read there 0.76 of the camera (docs/sensor.md).
int expect_sigma_bins(const std::vector<SigmaBin>& fit, const std::vector<SigmaBin>& real,
                      const std::vector<SigmaBin>& sim, const std::string& what) {
  int bins = 0;
  for (std::size_t b = 0; b < real.size() && b < sim.size() && b < fit.size(); ++b) {
    if (fit[b].windows < kMinBinWindows || real[b].windows < kMinBinWindows) continue;
    // A bin the simulation leaves (nearly) empty is a failure, not a bin skipped; from
    // kMinSimWindows its median is compared (the count itself moves with the draws).
    EXPECT_GE(sim[b].windows, kMinSimWindows) << what << " " << real[b].lo << "-" << real[b].hi
                                              << ": the simulation leaves it empty";
    if (sim[b].windows < kMinSimWindows) continue;
    ++bins;
    expect_in_band(sim[b].sigma, real[b].sigma,
                   what + " " + std::to_string(real[b].lo) + "-" + std::to_string(real[b].hi));
  }
  return bins;
}

TEST(DepthStats, FrameHalvesSplitTheRecording) {
  io::Intrinsics K;
  const std::vector<io::DepthImage> frames = real_frames(K);
  for (const auto& [a, b] : {std::pair{FrameHalf::even, FrameHalf::odd},
                             std::pair{FrameHalf::near, FrameHalf::far}}) {
    std::vector<std::size_t> both = frame_half(frames, K, a);
    const std::vector<std::size_t> other = frame_half(frames, K, b);
    EXPECT_EQ(both.size(), 6u);  // ceil(11 / 2)
    EXPECT_EQ(other.size(), 5u);
    both.insert(both.end(), other.begin(), other.end());
    std::sort(both.begin(), both.end());
    EXPECT_EQ(both, frame_half(frames, K, FrameHalf::all)) << to_string(a);
  }
  EXPECT_EQ(frame_half(frames, K, FrameHalf::odd), (std::vector<std::size_t>{1, 3, 5, 7, 9}));
  // The near half's frames are nearer: every one's median depth below every far one's.
  auto median_z = [&](std::size_t i) {
    std::vector<double> z;
    for (const std::uint16_t d : frames[i].data)
      if (d != 0) z.push_back(d * K.depth_scale);
    std::nth_element(z.begin(), z.begin() + static_cast<std::ptrdiff_t>(z.size() / 2), z.end());
    return z[z.size() / 2];
  };
  for (const std::size_t n : frame_half(frames, K, FrameHalf::near))
    for (const std::size_t f : frame_half(frames, K, FrameHalf::far))
      EXPECT_LE(median_z(n), median_z(f)) << n << " near, " << f << " far";
  for (const FrameHalf h : kFrameHalves) EXPECT_EQ(parse_frame_half(to_string(h)), h);
  try {
    (void)parse_frame_half("middle");
    ADD_FAILURE() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'middle'"), std::string::npos) << e.what();
  }
  std::vector<io::DepthImage> blank(1, frames[0]);
  std::fill(blank[0].data.begin(), blank[0].data.end(), 0);
  EXPECT_THROW((void)frame_half(blank, K, FrameHalf::near), std::invalid_argument);
}

// What the one-field model reproduces out of sample, with the issue's band 0.8-1.25:
// plane-fit sigma per depth bin (where the fit half has windows) and per angle bin, the
// pooled lag-1 correlation; the edge bands within the in-sample test's 30%, and the
// projector's side. What it does not (the structure statistics, flying pixels and holes)
// is asserted in HeldOutFidelity.IssueTwentyTargets, outside CI and red.
TEST(DepthStats, HeldOutFidelityOfTheOneFieldFit) {
  io::Intrinsics K;
  const std::vector<io::DepthImage> all = real_frames(K);
  for (const HeldOut& h : kHeldOut) {
    const std::string dir =
        "fit on " + std::string(to_string(h.fit)) + ", test on " + std::string(to_string(h.test));
    SCOPED_TRACE(dir);
    const HeldOutStats s = held_out(all, K, h);
    EXPECT_GE(expect_sigma_bins(s.fit.sigma_by_depth, s.real.sigma_by_depth, s.sim.sigma_by_depth,
                                "sigma by depth"),
              2);
    EXPECT_GE(expect_sigma_bins(s.fit.sigma_by_angle, s.real.sigma_by_angle, s.sim.sigma_by_angle,
                                "sigma by angle"),
              4);
    expect_in_band(s.sim.correlation[0], s.real.correlation[0], "lag-1 correlation");
    for (const auto& [name, re, se] : {std::tuple{"near left", s.real.near_left, s.sim.near_left},
                                       std::tuple{"near right", s.real.near_right, s.sim.near_right}}) {
      ASSERT_GE(re.edges, 50) << name;
      EXPECT_NEAR(se.invalid_1px / re.invalid_1px, 1.0, kFidelityEdgeTol) << name;
      EXPECT_NEAR(se.invalid_2px / re.invalid_2px, 1.0, kFidelityEdgeTol) << name;
    }
    EXPECT_EQ(s.sim.projector_side, s.real.projector_side);
  }
}

// The staleness tests compare presets with test::expect_fields_near, by the keys a scene
// file uses: those reach the members (in SI units, a degree key in radians), nested
// blocks included, and a key no struct has (or one that holds no number, as an enum) is a
// failure, not a skipped comparison.
TEST(DepthStats, PresetsAreComparedByTheirSceneKeys) {
  const NoiseParams p = NoiseParams::sr300();
  const test::NumberFields f(p);
  EXPECT_EQ(f.at("axial.a_m"), p.axial.a);
  EXPECT_EQ(f.at("dropouts.max_incidence_deg"), p.dropouts.max_incidence);
  EXPECT_EQ(f.at("axial.low_stride_px"), p.axial.low_stride_px);
  EXPECT_EQ(f.at("edges.drop_steps"), p.edges.drop_steps ? 1.0 : 0.0);
  EXPECT_EQ(f.at("quantize"), p.quantize ? 1.0 : 0.0);
  ASSERT_FALSE(p.axial.low_angle_term);  // so that a flag read as 1 whatever it holds fails
  EXPECT_EQ(f.at("axial.low_angle_term"), 0.0);
  EXPECT_NONFATAL_FAILURE((void)f.at("axial.a"), "no field axial.a");
  EXPECT_NONFATAL_FAILURE(test::expect_fields_near(p, p, {"axial.a"}, 0.01), "no field axial.a");
  EXPECT_NONFATAL_FAILURE((void)f.at("axial.kernel"), "axial.kernel is not a number");
  NoiseParams q = p;
  q.axial.c *= 1.02;
  EXPECT_NONFATAL_FAILURE(test::expect_fields_near(q, p, {"axial.c_per_m"}, 0.01),
                          "axial.c_per_m");
  test::expect_fields_near(q, p, {"axial.c_per_m"}, 0.03);
}

// The sr300 preset is calibrate-noise --structure two-scale on all 11 frames, rounded
// (docs/sensor.md, "The sr300 preset (issue 20)"): a fit that moves away from it means the
// preset is stale. Label fidelity-full with the held-out tests (one fit of about 35 s).
TEST(HeldOutFidelity, TheSr300PresetIsTheTwoScaleFit) {
  io::Intrinsics K;
  const std::vector<io::DepthImage> frames = real_frames(K);
  const DepthStats real = depth_stats(frames, K);
  NoiseParams quiet = NoiseParams::off();  // as calibrate-noise's shape correction
  quiet.quantize = true;
  const DepthStats shape = depth_stats(rerender_surfaces(frames, K, quiet, 1), K);
  const NoiseParams fit =
      fit_noise_rerendered(frames, K, real, &shape, NoiseParams::sr300_one_field()).params;
  constexpr double kPresetRelTol = 0.01;  // the preset's rounding
  // The flags and the grid stride are exact: a tolerance of 0 on them.
  test::expect_fields_near(fit, NoiseParams::sr300(),
                           {"axial.a_m", "axial.c_per_m", "axial.k_theta", "axial.correlation_px",
                            "axial.correlation_cols_px", "axial.low_share", "axial.low_rows_px",
                            "axial.low_cols_px", "axial.pixel_depth_power", "axial.angle_power",
                            "dropouts.max_incidence_deg", "dropouts.hole_rate"},
                           kPresetRelTol);
  // The power's range is the depth bins the frames fill: exact.
  test::expect_fields_near(fit, NoiseParams::sr300(),
                           {"axial.low_angle_term", "axial.low_stride_px", "axial.pixel_depth_ref_m",
                            "axial.pixel_depth_min_m", "axial.pixel_depth_max_m", "edges.drop_steps"},
                           0);
}

// The shape correction's render (rerender_surfaces with the noise off, so no lateral
// jitter) of a whole tilted plane is all surface. depth_surface_mesh puts each vertex
// 0.01 px off its pixel's ray: on the ray, Embree's robust triangle test can let a ray
// through exactly a vertex pass (RenderKit/embree#174, #181), and this plane came back
// with about 2100 one-pixel holes (650 per frame on the hand frames). With the preset's
// 0.1 px jitter the rays missed the vertices anyway (the first expectation).
TEST(ShapeRender, APlaneComesBackWithoutHoles) {
  io::Intrinsics K;
  K.fx = K.fy = 476.0;
  io::DepthImage plane{K.width, K.height, {}};
  for (int v = 0; v < K.height; ++v)
    for (int u = 0; u < K.width; ++u) {
      // z = 0.6 m + 0.3 x: tilted by 17 degrees about the vertical.
      const double z = 0.6 / (1 - 0.3 * (u - K.cx) / K.fx);
      plane.data.push_back(static_cast<std::uint16_t>(std::lround(z / K.depth_scale)));
    }
  NoiseParams quiet = NoiseParams::off();  // as calibrate-noise's shape correction
  quiet.quantize = true;
  const auto holes = [&](const NoiseParams& noise) {
    const io::DepthImage out = rerender_surfaces({plane}, K, noise, 1).at(0);
    long n = 0;  // away from the image border, where the surface's fill stops
    for (int v = 2; v + 2 < out.height; ++v)
      for (int u = 2; u + 2 < out.width; ++u)
        n += out.data[static_cast<std::size_t>(v) * out.width + u] == 0;
    return n;
  };
  NoiseParams jittered = quiet;
  jittered.lateral = NoiseParams::sr300().lateral;
  EXPECT_EQ(holes(jittered), 0);
  EXPECT_EQ(holes(quiet), 0) << "rays through the rebuilt mesh's vertices pass through it";
}

// A surface's rim as the shape render returns it: a 100 x 100 px square of a plane at 0.6 m
// on an empty background, each side's 100 edge pixels, and their depth. The camera saw every
// one of them. The rebuilt mesh ends at the edge pixels' centres and its vertices sit
// 0.01 px down and right of their rays, so without the rim's splats the top and left sides
// never came back without jitter (0.00 / 0.99 / 0.00 / 0.99, top / bottom / left / right)
// and with the preset's 0.1 px jitter about half of every side's rays fell off the rim
// (0.54 / 0.48 / 0.43 / 0.48; docs/sensor.md, "The shape render's rim"). A splat reaches
// half a pixel past its ray, 5 of the jitter's sigmas, so every edge pixel must come back
// with jitter too. It sits kRimSplatBehind_m (0.2 mm) behind the plane, so a rim pixel reads
// the plane or up to that behind it, to half a depth unit of rounding, never in front.
TEST(ShapeRenderRim, EveryEdgePixelOfASurfaceComesBack) {
  io::Intrinsics K;
  K.fx = K.fy = 476.0;
  constexpr int kLo = 100, kHi = 200;  // the square: pixels [kLo, kHi) both ways
  constexpr double kPlane_m = 0.6;
  io::DepthImage square{K.width, K.height, {}};
  square.data.assign(static_cast<std::size_t>(K.width) * K.height, 0);
  for (int v = kLo; v < kHi; ++v)
    for (int u = kLo; u < kHi; ++u)
      square.data[static_cast<std::size_t>(v) * K.width + u] =
          static_cast<std::uint16_t>(std::lround(kPlane_m / K.depth_scale));
  NoiseParams quiet = NoiseParams::off();  // as calibrate-noise's shape correction
  quiet.quantize = true;
  NoiseParams jittered = quiet;
  jittered.lateral = NoiseParams::sr300().lateral;
  const double kRounding_m = 0.5 * K.depth_scale;
  for (const auto& [noise, what] : {std::pair{quiet, "no jitter"}, std::pair{jittered, "jitter"}}) {
    SCOPED_TRACE(what);
    const io::DepthImage out = rerender_surfaces({square}, K, noise, 1).at(0);
    // Each side as (fixed coordinate, whether it is a row): its pixels run over [kLo, kHi).
    for (const auto& [side, at, row] :
         {std::tuple{"top", kLo, true}, std::tuple{"bottom", kHi - 1, true},
          std::tuple{"left", kLo, false}, std::tuple{"right", kHi - 1, false}}) {
      int back = 0;
      double nearest_m = 1, farthest_m = 0;  // of the rim pixels that came back
      for (int i = kLo; i < kHi; ++i) {
        const int u = row ? i : at, v = row ? at : i;
        const std::uint16_t raw = out.data[static_cast<std::size_t>(v) * out.width + u];
        if (raw == 0) continue;
        ++back;
        nearest_m = std::min(nearest_m, raw * K.depth_scale);
        farthest_m = std::max(farthest_m, raw * K.depth_scale);
      }
      EXPECT_EQ(back, kHi - kLo) << side;
      EXPECT_GE(nearest_m, kPlane_m - kRounding_m) << side << ": in front of the plane";
      EXPECT_LE(farthest_m, kPlane_m + kRimSplatBehind_m + kRounding_m) << side;
    }
  }
}

// The issue's held-out targets (issue 20), for the two-scale structure fitted by
// re-rendering (fit_noise_rerendered) on one half and compared on the other: plane-fit sigma
// per depth and per angle bin and quadratic-fit sigma per angle bin (bins the fit half
// holds 10 windows of), the correlation along rows and along columns at lags 1-4 (where
// the camera's is under kSmallCorrelation, within kSmallCorrelationTol instead of a
// ratio), the quadratic-beats-plane share, the flying-pixel rate (beside the bands) and
// the holes per frame within 0.8-1.25, and neighbour jumps > 20 mm within a factor of 2 (of
// at least 1 per million: the camera shows none); and, since the fit moves
// dropouts.max_incidence, the edge bands within the one-field test's 30%. Red today on a
// few of them (docs/sensor.md gives each ratio); label fidelity-full, outside CI, as
// robustness-full: four fits of about a minute each (4 draws). Each fit is one seed's
// (RerenderFitParams::seed): the near->far rows' lag 3 reads -0.032 to -0.103 over seeds
// 1-8, mean -0.057, and as widely at 16 draws (docs/sensor.md, "The fit half's share of a
// held-out miss").
TEST(HeldOutFidelity, IssueTwentyTargets) {
  io::Intrinsics K;
  const std::vector<io::DepthImage> all = real_frames(K);
  for (const HeldOut& h : kHeldOut) {
    SCOPED_TRACE("fit on " + std::string(to_string(h.fit)) + ", test on " +
                 std::string(to_string(h.test)));
    const HeldOutStats s = held_out(all, K, h, NoiseStructure::two_scale, true);
    // With each failure, how far every statistic outside the band rests on the test half's
    // frames: a miss of a few standard errors is the model's, one within a standard error
    // could be the frames'. (The fit half's frames move the fit too; that is not in it.)
    std::ostringstream spread;
    spread << std::setprecision(3) << "outside, with the leave-one-frame-out jackknife's se:";
    for (const TargetSpread& t : s.spread)
      if (t.all.e > 1) spread << " " << t.all.name << " " << t.all.value() << " +- " << t.se << ";";
    SCOPED_TRACE(spread.str());
    (void)expect_sigma_bins(s.fit.sigma_by_depth, s.real.sigma_by_depth, s.sim.sigma_by_depth,
                            "sigma by depth");
    (void)expect_sigma_bins(s.fit.sigma_by_angle, s.real.sigma_by_angle, s.sim.sigma_by_angle,
                            "sigma by angle");
    (void)expect_sigma_bins(s.fit.sigma_quad_by_angle, s.real.sigma_quad_by_angle,
                            s.sim.sigma_quad_by_angle, "quadratic sigma by angle");
    // A ratio of correlations near zero says nothing (the camera's rows read -0.13 at
    // lag 4).
    const auto correlation = [&](double sim, double real, const std::string& what) {
      if (std::abs(real) >= kSmallCorrelation) return expect_in_band(sim, real, what);
      EXPECT_NEAR(sim, real, kSmallCorrelationTol) << what;
    };
    for (int l = 0; l < 4; ++l) {
      correlation(s.sim.correlation_rows[l], s.real.correlation_rows[l],
                  "rows, lag " + std::to_string(l + 1));
      correlation(s.sim.correlation_cols[l], s.real.correlation_cols[l],
                  "columns, lag " + std::to_string(l + 1));
    }
    expect_in_band(s.sim.quad_beats_plane, s.real.quad_beats_plane, "quadratic beats plane");
    expect_in_band(s.sim.flying_band_rate, s.real.flying_band_rate, "flying rate beside bands");
    expect_in_band(s.sim.holes_per_frame, s.real.holes_per_frame, "holes per frame");
    const auto per_million = [](const DepthStats& d) {
      return d.neighbour_pairs > 0 ? 1e6 * static_cast<double>(d.neighbour_jumps) /
                                         static_cast<double>(d.neighbour_pairs)
                                   : 0.0;
    };
    EXPECT_LE(per_million(s.sim), 2 * std::max(per_million(s.real), 1.0));
    EXPECT_GE(per_million(s.sim), 0.5 * per_million(s.real));
    for (const auto& [name, re, se] : {std::tuple{"near left", s.real.near_left, s.sim.near_left},
                                       std::tuple{"near right", s.real.near_right, s.sim.near_right}}) {
      ASSERT_GE(re.edges, 50) << name;
      EXPECT_NEAR(se.invalid_1px / re.invalid_1px, 1.0, kFidelityEdgeTol) << name;
      EXPECT_NEAR(se.invalid_2px / re.invalid_2px, 1.0, kFidelityEdgeTol) << name;
    }
  }
}

// target_mismatch: the camera against itself costs nothing; each kind of statistic counts
// by its rule (a ratio's error is 1 at the band's edge, a small correlation's at 0.05 off,
// the cost the sum of their squares); the ones outside are named with their ratio. The
// steps below are exact: e is |ln(sim / real)| / ln(1.25).
TEST(DepthStats, TargetMismatchCountsTheIssuesStatistics) {
  io::Intrinsics K;
  const DepthStats real = depth_stats(real_frames(K), K);
  const TargetMismatch self = target_mismatch(real, real);
  EXPECT_EQ(self.cost, 0.0);
  EXPECT_TRUE(self.outside.empty());
  // 4 + 5 + 5 + 4 sigma bins (plane by depth and by angle, quadratic by angle and by
  // depth), 8 correlations, the share, 2 band pixels and the band's width, flying, holes.
  EXPECT_EQ(self.statistics, 32);
  ASSERT_LT(std::abs(real.correlation_rows[3]), kSmallCorrelation);  // -0.13
  ASSERT_GE(real.quad_beats_plane, kSmallCorrelation);
  DepthStats sim = real;
  sim.quad_beats_plane = real.quad_beats_plane * 1.25 * 1.25;  // e = 2: outside
  sim.correlation_rows[3] = real.correlation_rows[3] + 0.1;    // e = 2 as well
  sim.holes_per_frame = real.holes_per_frame / std::sqrt(1.25);  // e = 1/2: inside
  const TargetMismatch m = target_mismatch(real, sim);
  EXPECT_NEAR(m.cost, 4 + 4 + 0.25, 1e-9);
  ASSERT_EQ(m.outside.size(), 2u);
  EXPECT_EQ(m.outside[0].rfind("correlation rows lag 4 ", 0), 0u) << m.outside[0];
  EXPECT_EQ(m.outside[1], "quadratic beats plane 1.56");
  // A statistic the simulation reads as 0 is as far off as can be, not skipped, and so is
  // a bin it leaves without windows.
  sim = real;
  sim.flying_band_rate = 0;
  EXPECT_GT(target_mismatch(real, sim).cost, 100.0);
  sim = real;
  auto& steep = sim.sigma_quad_by_angle[4];  // 60-75 degrees
  ASSERT_GE(steep.windows, 10);
  steep.windows = kMinSimWindows - 1;
  const TargetMismatch lost = target_mismatch(real, sim);
  EXPECT_EQ(lost.statistics, 32);
  EXPECT_GT(lost.cost, 100.0);
  // A simulation whose bands decide no side is compared on the camera's image side.
  ASSERT_LT(real.projector_side, 0);  // projector image-left: the other side is near_right
  // Each edge statistic carries the image sides it read (3 real's + the simulation's),
  // so that a jackknife can tell a side that flips; the others carry none.
  sim = real;
  sim.projector_side = 1;
  for (const TargetStatistic& t : target_mismatch(real, sim).compared)
    EXPECT_EQ(t.sides, t.name.rfind("other side ", 0) == 0 ? -3 + 1 : 0) << t.name;
  sim.projector_side = 0;
  EXPECT_EQ(target_mismatch(real, sim).statistics, 32);
  sim.near_right.band_median_px = 2 * real.near_right.band_median_px;
  EXPECT_NE(target_mismatch(real, sim).outside.back().find("other side band median px 2.00"),
            std::string::npos);
}

// target_jackknife: paired over the frames, so a frame leaves with every draw of it; the
// value on all frames is target_mismatch's; the spread is the jackknife's, checked on one
// statistic against leave-one-out readings made here, a frame or two a group; NaN where
// nothing can be read without a group; too few frames or groups, and draws that do not
// divide, are refused.
TEST(DepthStats, TargetJackknifeLeavesOneFrameOutOnBothSides) {
  io::Intrinsics K;
  std::vector<io::DepthImage> real = real_frames(K);
  real.resize(4);
  const auto finite_se = [](const std::vector<TargetSpread>& v) {
    int n = 0;
    for (const TargetSpread& t : v) n += std::isfinite(t.se) ? 1 : 0;
    return n;
  };
  // The camera against itself, and against two draws of itself: nothing to spread. With
  // the draws, a jackknife that left only one copy of a frame out would read the other
  // copy as a frame of its own and spread. (Pooled over twice the pixels, a correlation's
  // sums round differently: kSums.)
  constexpr double kSums = 1e-12;
  std::vector<io::DepthImage> twice = real;
  twice.insert(twice.end(), real.begin(), real.end());
  const DepthStats stats = depth_stats(real, K);
  for (const auto* sim : {&real, &twice}) {
    const std::vector<TargetSpread> self = target_jackknife(real, *sim, K);
    ASSERT_EQ(self.size(), static_cast<std::size_t>(target_mismatch(stats, stats).statistics));
    EXPECT_GE(finite_se(self), 28);
    for (const TargetSpread& t : self) {
      EXPECT_NEAR(t.all.value(), t.all.difference ? 0.0 : 1.0, kSums) << t.all.name;
      if (std::isfinite(t.se)) {
        EXPECT_NEAR(t.se, 0.0, kSums) << t.all.name;
      }
    }
  }
  // Frame 0 paired with frame 1's image: the figures on all frames are target_mismatch's,
  // and they rest on frame 0, so they spread.
  std::vector<io::DepthImage> swapped = real;
  swapped[0] = real[1];
  const std::vector<TargetSpread> spread = target_jackknife(real, swapped, K);
  const TargetMismatch all =
      target_mismatch(depth_stats(real, K), depth_stats(swapped, K, {}, &real));
  ASSERT_EQ(spread.size(), all.compared.size());
  int spreading = 0;
  for (std::size_t k = 0; k < spread.size(); ++k) {
    EXPECT_EQ(spread[k].all.name, all.compared[k].name);
    EXPECT_EQ(spread[k].all.value(), all.compared[k].value()) << all.compared[k].name;
    spreading += spread[k].se > 0 ? 1 : 0;
  }
  EXPECT_GE(spreading, 20);
  // Holes per frame, left out by hand: sqrt((g - 1) / g sum (v_i - mean)^2), one frame a
  // group, and with at most 2 groups frames 0-1 and 2-3.
  const auto holes_se = [&](const std::vector<TargetSpread>& v) {
    const auto it = std::find_if(v.begin(), v.end(),
                                 [](const TargetSpread& t) { return t.all.name == "holes per frame"; });
    return it == v.end() ? std::nan("") : it->se;
  };
  for (const std::size_t per_group : {1u, 2u}) {
    SCOPED_TRACE(std::to_string(per_group) + " frames a group");
    std::vector<double> v;
    for (std::size_t i = 0; i < real.size() / per_group; ++i) {
      std::vector<io::DepthImage> r, s;
      for (std::size_t f = 0; f < real.size(); ++f)
        if (f / per_group != i) r.push_back(real[f]), s.push_back(swapped[f]);
      v.push_back(depth_stats(s, K, {}, &r).holes_per_frame / depth_stats(r, K).holes_per_frame);
    }
    double mean = 0, ss = 0;
    for (const double x : v) mean += x / static_cast<double>(v.size());
    for (const double x : v) ss += (x - mean) * (x - mean);
    const double g = static_cast<double>(v.size());
    const double se = holes_se(per_group == 1 ? spread : target_jackknife(real, swapped, K, {}, 2));
    EXPECT_GT(se, 0.0);
    EXPECT_NEAR(se, std::sqrt((g - 1) / g * ss), 1e-12);
  }
  // Without frame 0 the others (a 14 x 14 px patch each) hold no flat window: nothing can
  // be read, so nothing has a spread, and the figures on all frames still stand.
  std::vector<io::DepthImage> patches(3, real[0]);
  for (std::size_t f = 1; f < 3; ++f)
    for (int v = 0; v < K.height; ++v)
      for (int u = 0; u < K.width; ++u)
        if (v < 200 || v >= 214 || u < 300 || u >= 314)
          patches[f].data[static_cast<std::size_t>(v) * K.width + u] = 0;
  ASSERT_THROW((void)depth_stats({patches[1], patches[2]}, K), std::invalid_argument);
  const std::vector<TargetSpread> unreadable = target_jackknife(patches, patches, K);
  ASSERT_FALSE(unreadable.empty());
  for (const TargetSpread& t : unreadable) {
    EXPECT_TRUE(std::isnan(t.se)) << t.all.name;
    EXPECT_NEAR(t.all.value(), t.all.difference ? 0.0 : 1.0, kSums) << t.all.name;
  }
  // Refusals.
  const std::vector<io::DepthImage> two(real.begin(), real.begin() + 2);
  EXPECT_NE(test::error_of<std::invalid_argument>([&] { (void)target_jackknife(two, two, K); })
                .find("2 frames; leaving one out needs at least 3"),
            std::string::npos);
  const std::vector<io::DepthImage> five(twice.begin(), twice.begin() + 5);
  EXPECT_NE(test::error_of<std::invalid_argument>([&] { (void)target_jackknife(real, five, K); })
                .find("5 simulated images are not draws of 4 frames"),
            std::string::npos);
  EXPECT_NE(test::error_of<std::invalid_argument>([&] { (void)target_jackknife(real, real, K, {}, 1); })
                .find("max_groups = 1: must be >= 2"),
            std::string::npos);
}

// jackknife_se: sqrt((g - 1) / g sum (v_i - mean)^2); NaN with a reading missing (NaN) or
// fewer than 2. leave_groups_out: one pair a group, each without its group's frames on
// both sides (and every draw of them), nullopt where they cannot be read.
TEST(DepthStats, LeaveGroupsOutAndTheJackknifesSe) {
  EXPECT_NEAR(jackknife_se({1.0, 2.0, 3.0}), std::sqrt(2.0 / 3.0 * 2.0), 1e-15);
  EXPECT_EQ(jackknife_se({4.0, 4.0}), 0.0);
  EXPECT_TRUE(std::isnan(jackknife_se({1.0, std::nan(""), 3.0})));
  EXPECT_TRUE(std::isnan(jackknife_se({1.0})));
  io::Intrinsics K;
  std::vector<io::DepthImage> real = real_frames(K);
  real.resize(4);
  std::vector<io::DepthImage> twice = real;  // two draws of each frame, draw-major
  twice.insert(twice.end(), real.begin(), real.end());
  const std::vector<std::optional<LeftOut>> left = leave_groups_out(real, twice, K, {}, 2);
  ASSERT_EQ(left.size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    ASSERT_TRUE(left[i].has_value()) << i;
    EXPECT_EQ(left[i]->real.frames, 2) << i;
    EXPECT_EQ(left[i]->sim.frames, 4) << i;
    // Without frames 0-1 (group 0) the camera reads what frames 2-3 read alone.
    const std::vector<io::DepthImage> kept(real.begin() + 2 * static_cast<long>(1 - i),
                                           real.begin() + 2 * static_cast<long>(2 - i));
    EXPECT_EQ(left[i]->real.windows, depth_stats(kept, K).windows) << i;
    EXPECT_EQ(left[i]->real.correlation_rows, depth_stats(kept, K).correlation_rows) << i;
  }
  EXPECT_EQ(leave_groups_out(real, twice, K).size(), 4u);  // one frame a group
  // Frames 1 and 2 a 14 x 14 px patch each, which holds no flat window: without frame 0
  // nothing can be read, with it everything can.
  std::vector<io::DepthImage> patches(3, real[0]);
  for (std::size_t f = 1; f < 3; ++f)
    for (int v = 0; v < K.height; ++v)
      for (int u = 0; u < K.width; ++u)
        if (v < 200 || v >= 214 || u < 300 || u >= 314)
          patches[f].data[static_cast<std::size_t>(v) * K.width + u] = 0;
  const std::vector<std::optional<LeftOut>> unreadable = leave_groups_out(patches, patches, K);
  ASSERT_EQ(unreadable.size(), 3u);
  EXPECT_FALSE(unreadable[0].has_value());
  EXPECT_TRUE(unreadable[1].has_value());
  EXPECT_TRUE(unreadable[2].has_value());
}

// The first two shared frames and their statistics: enough for a fit's mechanics.
struct TwoFrames {
  io::Intrinsics K;
  std::vector<io::DepthImage> frames;
  DepthStats stats;
};
TwoFrames two_frames() {
  TwoFrames t;
  t.frames = real_frames(t.K);
  t.frames.resize(2);
  t.stats = depth_stats(t.frames, t.K);
  return t;
}

// The two-scale fit's note, "... target mismatch X (start Y) ...": {X, Y}; NaN, and a
// failure, where there is no such note.
std::pair<double, double> noted_mismatch(const NoiseFit& fit) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (const std::string& n : fit.notes) {
    if (n.rfind("two-scale structure", 0) != 0) continue;
    double cost = nan, start = nan;
    const std::size_t at = n.find("target mismatch ");
    if (at == std::string::npos ||
        std::sscanf(n.c_str() + at, "target mismatch %lf (start %lf)", &cost, &start) != 2)
      ADD_FAILURE() << "no target mismatch in: " << n;
    return {cost, start};
  }
  ADD_FAILURE() << "no two-scale note";
  return {nan, nan};
}

// fit_noise_rerendered on two of the shared frames, one sweep: the pattern search only
// keeps improvements, so the fit costs no more than its start (the note gives both), the
// fitted block is the two-scale structure a scene accepts, and 1 and 2 threads give the
// same fit; fit_noise refuses the structure it cannot fit.
TEST(DepthStats, RerenderedFitImprovesOnItsStartForAnyThreadCount) {
  const TwoFrames t = two_frames();
  RerenderFitParams p;
  p.sweeps = 1;
  p.threads = 1;
  const NoiseFit one =
      fit_noise_rerendered(t.frames, t.K, t.stats, nullptr, NoiseParams::sr300_one_field(), p);
  p.threads = 2;
  const NoiseFit two =
      fit_noise_rerendered(t.frames, t.K, t.stats, nullptr, NoiseParams::sr300_one_field(), p);
  EXPECT_EQ(noise_yaml(one.params), noise_yaml(two.params));
  EXPECT_EQ(one.notes, two.notes);
  const AxialNoise& ax = one.params.axial;
  EXPECT_FALSE(ax.low_angle_term);
  EXPECT_GT(ax.low_share, 0.0);
  EXPECT_EQ(ax.kernel, AxialKernel::gaussian);
  one.params.validate();
  // The one-field fit that starts the search has no depth power, whatever its start has.
  const NoiseFit from_preset = fit_noise(t.stats, NoiseParams::sr300());
  EXPECT_EQ(from_preset.params.axial.pixel_depth_power, 0.0);
  from_preset.params.validate();
  // "... target mismatch X (start Y) ...": X < Y (the start is not the fit).
  const auto [cost, start] = noted_mismatch(one);
  EXPECT_LT(cost, start) << "one sweep of up to 23 renders found nothing better than the start";
  for (const std::string& n : one.notes)
    EXPECT_EQ(n.find("max_incidence, min_signal kept"), std::string::npos) << n;
  EXPECT_NE(test::error_of<std::invalid_argument>([&] {
              (void)fit_noise(t.stats, NoiseParams::sr300_one_field(), nullptr,
                              NoiseStructure::two_scale);
            }).find("fit_noise_rerendered"),
            std::string::npos);
  p.sweeps = -1;
  EXPECT_NE(test::error_of<std::invalid_argument>([&] {
              (void)fit_noise_rerendered(t.frames, t.K, t.stats, nullptr, NoiseParams::sr300_one_field(), p);
            }).find("sweeps = -1"),
            std::string::npos);
  p.sweeps = 1;
  p.draws = 0;
  EXPECT_NE(test::error_of<std::invalid_argument>([&] {
              (void)fit_noise_rerendered(t.frames, t.K, t.stats, nullptr, NoiseParams::sr300_one_field(), p);
            }).find("draws = 0"),
            std::string::npos);
  EXPECT_EQ(parse_noise_structure("two-scale"), NoiseStructure::two_scale);
}

// rerender_surfaces' draws: draw 0 is the one-draw render, byte for byte, the others are
// the same casts with fresh noise (every draw differs from every other), draw-major; the
// pooled statistics count every draw (holes per frame over n x draws frames); draws < 1 is
// refused by name.
TEST(DepthStats, RerenderedDrawsStartWithTheOneDrawRender) {
  const TwoFrames t = two_frames();
  const io::Intrinsics& K = t.K;
  const std::vector<io::DepthImage>& frames = t.frames;
  const NoiseParams noise = NoiseParams::sr300();
  const std::vector<io::DepthImage> one = rerender_surfaces(frames, K, noise, 5);
  const std::vector<io::DepthImage> three = rerender_surfaces(frames, K, noise, 5, 3);
  ASSERT_EQ(one.size(), 2u);
  ASSERT_EQ(three.size(), 6u);
  for (std::size_t f = 0; f < 2; ++f) {
    EXPECT_EQ(three[f].data, one[f].data) << "frame " << f;
    for (std::size_t d = 1; d < 3; ++d) {
      const io::DepthImage& img = three[d * 2 + f];
      EXPECT_EQ(img.width, one[f].width);
      EXPECT_EQ(img.height, one[f].height);
      EXPECT_NE(img.data, three[(d - 1) * 2 + f].data) << "frame " << f << ", draw " << d;
      // The same surface: the valid pixels nearly all the same (holes and edges aside).
      long both = 0, either = 0;
      for (std::size_t k = 0; k < img.data.size(); ++k) {
        both += img.data[k] != 0 && one[f].data[k] != 0;
        either += img.data[k] != 0 || one[f].data[k] != 0;
      }
      EXPECT_GT(static_cast<double>(both), 0.95 * static_cast<double>(either)) << "draw " << d;
    }
  }
  // Pooled: the holes of every draw count, over all 6 images.
  double holes = 0;
  for (std::size_t d = 0; d < 3; ++d)
    holes += 2 * depth_stats({three[2 * d], three[2 * d + 1]}, K).holes_per_frame;
  ASSERT_GT(holes, 0);
  EXPECT_DOUBLE_EQ(6 * depth_stats(three, K).holes_per_frame, holes);
  EXPECT_NE(test::error_of<std::invalid_argument>([&] {
              (void)rerender_surfaces(frames, K, noise, 5, 0);
            }).find("draws = 0"),
            std::string::npos);
}

// The fit reads its candidates on the images rerender_surfaces returns for them: with no
// sweep the fit is its start, and the mismatch its note gives is what the same model's
// draws read (the same casts, frame keys and seed).
TEST(DepthStats, RerenderedFitReadsWhatRerenderSurfacesReturns) {
  const TwoFrames t = two_frames();
  RerenderFitParams p;
  p.sweeps = 0;
  p.draws = 2;
  const NoiseFit fit = fit_noise_rerendered(t.frames, t.K, t.stats, nullptr, NoiseParams::sr300_one_field(), p);
  const double cost = noted_mismatch(fit).first;
  ASSERT_GT(cost, 0);
  // Read as the fit reads: holes where the camera saw a surface.
  const std::vector<io::DepthImage> drawn =
      rerender_surfaces(t.frames, t.K, fit.params, p.seed, 2);
  const double read = target_mismatch(t.stats, depth_stats(drawn, t.K, {}, &t.frames)).cost;
  EXPECT_NEAR(read, cost, 0.005 * cost);  // the note gives 3 digits
  // Another seed's draws read differently: the comparison is not the fit's draws again.
  const std::vector<io::DepthImage> compared =
      rerender_surfaces(t.frames, t.K, fit.params, kCompareSeed, 2);
  const double other = target_mismatch(t.stats, depth_stats(compared, t.K, {}, &t.frames)).cost;
  EXPECT_NE(other, read);  // 157 against 117 on these t.frames
}

// RerenderFitParams::lateral_sigma_px: the frames are cast with the jitter given, the block
// keeps it and its note says so, the cost noted is what that block's draws read, and the
// start's jitter (0.1 px) casts other images; a value the model refuses is named.
TEST(DepthStats, RerenderedFitCastsWithTheLateralJitterGiven) {
  const TwoFrames t = two_frames();
  RerenderFitParams p;
  p.sweeps = 0;
  p.draws = 1;
  p.lateral_sigma_px = 0;
  const NoiseFit fit =
      fit_noise_rerendered(t.frames, t.K, t.stats, nullptr, NoiseParams::sr300_one_field(), p);
  EXPECT_EQ(fit.params.lateral.sigma_px, 0.0);
  EXPECT_TRUE(std::any_of(fit.notes.begin(), fit.notes.end(), [](const std::string& n) {
    return n.rfind("lateral.sigma_px 0 px as given, dropouts.min_signal kept", 0) == 0;
  })) << ::testing::PrintToString(fit.notes);
  const double cost = noted_mismatch(fit).first;
  ASSERT_GT(cost, 0);
  const std::vector<io::DepthImage> drawn =
      rerender_surfaces(t.frames, t.K, fit.params, p.seed, 1);
  const double read = target_mismatch(t.stats, depth_stats(drawn, t.K, {}, &t.frames)).cost;
  EXPECT_NEAR(read, cost, 0.005 * cost);  // the note gives 3 digits
  p.lateral_sigma_px.reset();
  const NoiseFit start =
      fit_noise_rerendered(t.frames, t.K, t.stats, nullptr, NoiseParams::sr300_one_field(), p);
  EXPECT_EQ(start.params.lateral.sigma_px, NoiseParams::sr300_one_field().lateral.sigma_px);
  EXPECT_NE(noted_mismatch(start).first, cost);
  // Refused up front, by the fit (the sensor would refuse it too, later, in its own words).
  p.lateral_sigma_px = -0.5;
  const std::string e = test::error_of<std::invalid_argument>([&] {
    (void)fit_noise_rerendered(t.frames, t.K, t.stats, nullptr, NoiseParams::sr300_one_field(), p);
  });
  EXPECT_EQ(e.rfind("fit_noise_rerendered: lateral_sigma_px: noise.lateral.sigma_px = -0.5", 0), 0u)
      << e;
}

// The estimator's reading of correlated noise: white reads white with the plane fit's own
// 3 dof taken into account; a wider kernel reads a higher lag-1 correlation (rising to
// about 3 px, then flat near 0.9: the quadratic fit removes what is smoother) and a lower
// sigma (fit_noise bisects on the lag-1 reading).
TEST(DepthStats, WindowResponseOfCorrelatedNoise) {
  const WindowResponse white = window_response(0.0);
  EXPECT_NEAR(white.variance_factor, 1.0, 1e-12);
  EXPECT_LT(std::abs(white.correlation[0]), 0.05);
  double last = -1, last_var = 2;
  for (int i = 1; i <= 20; ++i) {
    const double s = 0.3 * i;
    const WindowResponse r = window_response(s);
    if (s < 3.0) {
      EXPECT_GT(r.correlation[0], last + 1e-3) << s;
    } else {
      EXPECT_GE(r.correlation[0], last - 1e-4) << s;
    }
    EXPECT_LT(r.variance_factor, last_var) << s;
    last = r.correlation[0];
    last_var = r.variance_factor;
  }
  // Small width: near the noise's own exp(-1 / 4 s^2) at lag 1, less what the fit takes
  // (0.06 at 0.8 px).
  EXPECT_NEAR(window_response(0.8).correlation[0], std::exp(-1.0 / (4 * 0.64)), 0.1);
  EXPECT_THROW((void)window_response(1.0, 3), std::invalid_argument);
}

// An axial field alone (sigma 1 mm, quantized as the camera's) on a fronto-parallel wall at
// 0.6 m filling the default camera's image, 6 frames, read by depth_stats; `n` gets the
// rest of the setting.
DepthStats wall_field_stats(NoiseParams& n) {
  n.axial.enabled = true;
  n.axial.a = 0.001;
  n.axial.c = 0;
  n.axial.k_theta = 0;
  n.quantize = true;  // 0.125 mm steps under 1 mm noise, as the camera's
  const CameraParams camera;
  const std::size_t pixels = static_cast<std::size_t>(camera.intrinsics.width) * camera.intrinsics.height;
  const std::vector<float> depth(pixels, 0.6F), zero(pixels, 0.0F), one(pixels, 1.0F);
  const std::vector<std::uint8_t> lit(pixels, 1);
  const NoiseInput wall{camera.intrinsics.width, camera.intrinsics.height, depth, zero, one, one,
                        one, lit};
  SensorNoise noise(n, camera);
  std::vector<io::DepthImage> frames(6);
  std::vector<float> depth_m;
  for (std::size_t f = 0; f < frames.size(); ++f) noise.apply(wall, 4, f, 2, frames[f], depth_m);
  return depth_stats(frames, camera.intrinsics);
}

// `s` reads along rows and along columns at lags 1..lags what `r` predicts, within `tol`.
void expect_reads_as(const DepthStats& s, const WindowResponse& r, double tol,
                     int lags = kCorrelationLags) {
  for (int l = 0; l < lags; ++l) {
    EXPECT_NEAR(s.correlation_rows[l], r.correlation_rows[l], tol) << "rows, lag " << l + 1;
    EXPECT_NEAR(s.correlation_cols[l], r.correlation_cols[l], tol) << "columns, lag " << l + 1;
  }
}

// The two-term anisotropic field (issue 20) through the estimator: the sensor's field on a
// fronto-parallel wall, read by depth_stats, gives what window_response predicts along rows
// and along columns, and the quadratic-to-plane sigma ratio; the one-field isotropic model
// reads the same both ways.
TEST(DepthStats, WindowResponsePredictsTheTwoTermFieldsReading) {
  constexpr double kRhoTol = 0.03;       // seen: within 0.009
  constexpr double kRatioRelTol = 0.03;  // the quadratic's sigma over the plane's (seen: 0.1%)
  NoiseParams n = NoiseParams::off();
  n.axial.correlation_px = 1.2;
  n.axial.correlation_cols_px = 2.0;
  n.axial.low_share = 0.5;
  n.axial.low_rows_px = 5;
  n.axial.low_cols_px = 8;
  const DepthStats s = wall_field_stats(n);
  const WindowResponse r = window_response(n.axial, s.window);
  expect_reads_as(s, r, kRhoTol);
  EXPECT_GT(r.correlation_cols[2] - r.correlation_rows[2], 0.1);  // anisotropic, and read so
  ASSERT_EQ(s.scales.size(), 3u);
  EXPECT_NEAR(s.scales[1].sigma_quad / s.scales[1].sigma,
              std::sqrt(r.quad_variance_factor / r.variance_factor),
              kRatioRelTol * std::sqrt(r.quad_variance_factor / r.variance_factor));
  // Isotropic: the same reading both ways, and the one-field overload's.
  const WindowResponse iso = window_response(1.6);
  AxialNoise one_field;
  one_field.correlation_px = 1.6;
  const WindowResponse same = window_response(one_field);
  for (int l = 0; l < kCorrelationLags; ++l) {
    EXPECT_NEAR(iso.correlation_rows[l], iso.correlation_cols[l], 1e-12) << l;
    EXPECT_EQ(iso.correlation_rows[l], same.correlation_rows[l]) << l;
  }
  EXPECT_EQ(iso.variance_factor, same.variance_factor);
  one_field.low_share = 1;
  EXPECT_THROW((void)window_response(one_field), std::invalid_argument);
  // The two-term fit: a field that reads as this one does, along rows and columns, and
  // the sigma back. The widths themselves are not all pinned by these readings (seen: 1.25
  // x 2.12 px, share 0.58, low field 14.5 x 5 px for 1.2 x 2.0, 0.5, 5 x 8), so the test
  // asserts the readings, the anisotropy's direction and sigma.
  constexpr double kFitRhoTol = 0.05;    // seen: within 0.03
  constexpr double kFitRatioTol = 0.05;  // quadratic over plane variance (seen: 0.02)
  constexpr double kFitSigmaRelTol = 0.15;  // seen: 9%
  const NoiseFit fit =
      fit_noise(s, NoiseParams::sr300_one_field(), nullptr, NoiseStructure::two_term);
  const AxialNoise& f = fit.params.axial;
  const WindowResponse fr = window_response(f, s.window);
  expect_reads_as(s, fr, kFitRhoTol, 4);
  EXPECT_NEAR(fr.quad_variance_factor / fr.variance_factor,
              r.quad_variance_factor / r.variance_factor, kFitRatioTol);
  EXPECT_GT(f.cols_px(), f.rows_px());
  EXPECT_GT(f.low_share, 0.2);
  EXPECT_NEAR(f.sigma(0.6, 0.0), n.axial.a, kFitSigmaRelTol * n.axial.a);
  ASSERT_FALSE(fit.notes.empty());
  EXPECT_EQ(fit.notes[0].rfind("structure: ", 0), 0u) << fit.notes[0];
}

// The Matern-5/2 field (issue 20) through the estimator: the sensor's field on a
// fronto-parallel wall, read by depth_stats, gives what window_response predicts along rows
// and along columns; the matern52 structure fit reads back as the field does, with sigma.
TEST(DepthStats, WindowResponsePredictsTheMaternFieldsReading) {
  constexpr double kRhoTol = 0.03;       // seen: within 0.01
  constexpr double kRatioRelTol = 0.05;  // the quadratic's sigma over the plane's (seen: 1%)
  NoiseParams n = NoiseParams::off();
  n.axial.kernel = AxialKernel::matern52;
  n.axial.correlation_px = 4.0;
  n.axial.correlation_cols_px = 7.0;
  const DepthStats s = wall_field_stats(n);
  const WindowResponse r = window_response(n.axial, s.window);
  expect_reads_as(s, r, kRhoTol);
  ASSERT_EQ(s.scales.size(), 3u);
  const double ratio = std::sqrt(r.quad_variance_factor / r.variance_factor);
  EXPECT_NEAR(s.scales[1].sigma_quad / s.scales[1].sigma, ratio, kRatioRelTol * ratio);
  constexpr double kFitRhoTol = 0.05;       // seen: within 0.02
  constexpr double kFitRangeRelTol = 0.10;  // seen: 4.2 x 7.3 px for 4 x 7
  constexpr double kFitSigmaRelTol = 0.10;  // seen: 4%
  const NoiseFit fit =
      fit_noise(s, NoiseParams::sr300_one_field(), nullptr, NoiseStructure::matern52);
  const AxialNoise& f = fit.params.axial;
  EXPECT_EQ(f.kernel, AxialKernel::matern52);
  EXPECT_EQ(f.low_share, 0.0);
  const WindowResponse fr = window_response(f, s.window);
  expect_reads_as(s, fr, kFitRhoTol, 4);
  // One field's two ranges are pinned by these readings, unlike the two-term fit's five
  // parameters: they come back.
  EXPECT_NEAR(f.rows_px(), 4.0, kFitRangeRelTol * 4.0);
  EXPECT_NEAR(f.cols_px(), 7.0, kFitRangeRelTol * 7.0);
  EXPECT_NEAR(f.sigma(0.6, 0.0), n.axial.a, kFitSigmaRelTol * n.axial.a);
  ASSERT_FALSE(fit.notes.empty());
  EXPECT_EQ(fit.notes[0].rfind("structure: pixel-scale field (matern52)", 0), 0u) << fit.notes[0];
  // The one-field and two-term fits are of Gaussian fields whatever the start's kernel (their
  // widths would otherwise be read as ranges).
  NoiseParams start = NoiseParams::sr300_one_field();
  start.axial.kernel = AxialKernel::matern52;
  EXPECT_EQ(fit_noise(s, start).params.axial.kernel, AxialKernel::gaussian);
  EXPECT_EQ(fit_noise(s, start, nullptr, NoiseStructure::two_term).params.axial.kernel,
            AxialKernel::gaussian);
  EXPECT_EQ(parse_noise_structure("matern52"), NoiseStructure::matern52);
  EXPECT_EQ(to_string(NoiseStructure::matern52), "matern52");
  EXPECT_NE(test::error_of<std::invalid_argument>([] { (void)parse_noise_structure("cauchy"); })
                .find("'cauchy': expected one-field, two-term, matern52 or two-scale"),
            std::string::npos);
}

// AxialReading, what calibrate-noise's report draws for a block: the whole sigma through
// the fields' window factor, except that without the low field's angle term (two-scale)
// the angle term is read through the pixel-scale field's factor alone, which keeps more of
// it than the mix does.
TEST(DepthStats, AxialReadingReadsTheAngleTermAsThePixelFields) {
  AxialNoise ax;
  ax.a = 0.0005;
  ax.c = 0;
  ax.k_theta = ax.a * std::sqrt(0.6) / 4;  // t = a at 60 degrees and 0.6 m
  ax.correlation_px = 1.5;
  ax.low_share = 0.9;
  ax.low_rows_px = 6;
  ax.low_cols_px = 6;
  const double theta = std::numbers::pi / 3;
  const double mix = window_response(ax).variance_factor;
  AxialNoise pixel = ax;
  pixel.low_share = 0;
  const double pix = window_response(pixel).variance_factor;
  ASSERT_GT(pix, 2 * mix);  // a plane fit takes up most of the low field
  EXPECT_NEAR(AxialReading(ax).sigma(0.6, theta), std::sqrt(mix) * 2 * ax.a, 1e-12);
  ax.low_angle_term = false;
  EXPECT_NEAR(AxialReading(ax).sigma(0.6, 0.0), std::sqrt(mix) * ax.a, 1e-12);
  EXPECT_NEAR(AxialReading(ax).sigma(0.6, theta), ax.a * std::sqrt(mix + pix), 1e-12);
}

// window_response sums the fields' covariance as a Kronecker product; the dense sums of
// the definition (C, the plane's and quadratic's residual makers P and Q, entry by entry)
// give the same figures.
TEST(DepthStats, WindowResponseIsTheDenseSum) {
  for (const AxialKernel kernel : {AxialKernel::gaussian, AxialKernel::matern52}) {
    SCOPED_TRACE(to_string(kernel));
    constexpr int n = 9, N = n * n;
    AxialNoise ax;
    ax.kernel = kernel;  // the pixel-scale field's; the low one is Gaussian
    const bool matern = kernel == AxialKernel::matern52;  // ranges from 3 px (AxialNoise)
    const double wu = matern ? 3.5 : 0.9, wv = matern ? 5.0 : 1.7;
    ax.correlation_px = wu;
    ax.correlation_cols_px = wv;
    ax.low_share = 0.4;
    ax.low_rows_px = 3;
    ax.low_cols_px = 7;
    Eigen::MatrixXd C = Eigen::MatrixXd::Zero(N, N);
    for (int a = 0; a < N; ++a)
      for (int b = 0; b < N; ++b) {
        const double du = a % n - b % n, dv = a / n - b / n;
        auto rho = [&](double su, double sv) {
          return std::exp(-du * du / (4 * su * su) - dv * dv / (4 * sv * sv));
        };
        auto matern_rho = [](double d, double r) {
          const double x = std::sqrt(5.0) * std::abs(d) / r;
          return (1 + x + x * x / 3) * std::exp(-x);
        };
        const double pixel = matern ? matern_rho(du, wu) * matern_rho(dv, wv) : rho(wu, wv);
        C(a, b) = (1 - ax.low_share) * pixel + ax.low_share * rho(3, 7);
      }
    auto residual_maker = [&](int terms) {
      Eigen::MatrixXd X(N, terms);
      for (int a = 0; a < N; ++a) {
        const double x = (a % n - 0.5 * (n - 1)) / n, y = (a / n - 0.5 * (n - 1)) / n;
        const double all[6] = {1.0, x, y, x * x, x * y, y * y};
        for (int t = 0; t < terms; ++t) X(a, t) = all[t];
      }
      return Eigen::MatrixXd(Eigen::MatrixXd::Identity(N, N) -
                             X * (X.transpose() * X).inverse() * X.transpose());
    };
    const Eigen::MatrixXd P = residual_maker(3), Q = residual_maker(6);
    const Eigen::MatrixXd QCQ = Q * C * Q;
    const WindowResponse r = window_response(ax, n);
    constexpr double kTol = 1e-10;
    EXPECT_NEAR(r.variance_factor, (P * C * P).trace() / (N - 3), kTol);
    EXPECT_NEAR(r.quad_variance_factor, QCQ.trace() / (N - 6), kTol);
    for (int lag = 1; lag <= kCorrelationLags; ++lag) {
      double ab = 0, aa = 0, bb = 0, ab_c = 0, aa_c = 0, bb_c = 0;
      for (int a = 0; a < N; ++a) {
        if (a % n + lag < n) ab += QCQ(a, a + lag), aa += QCQ(a, a), bb += QCQ(a + lag, a + lag);
        if (a / n + lag < n)
          ab_c += QCQ(a, a + lag * n), aa_c += QCQ(a, a), bb_c += QCQ(a + lag * n, a + lag * n);
      }
      EXPECT_NEAR(r.correlation_rows[lag - 1], ab / std::sqrt(aa * bb), kTol) << lag;
      EXPECT_NEAR(r.correlation_cols[lag - 1], ab_c / std::sqrt(aa_c * bb_c), kTol) << lag;
      if (lag <= 4) {
        EXPECT_NEAR(r.correlation[lag - 1], (ab + ab_c) / std::sqrt((aa + aa_c) * (bb + bb_c)), kTol);
      }
    }
  }
}

// A fronto-parallel wall at 0.6 m, 300 x 225 px (20 x 15 windows of 15 px), depth in
// 0.1 mm units, plus `field(u, v)` [m].
template <class Field>
io::DepthImage wall(io::Intrinsics& K, Field field) {
  K = io::Intrinsics{};
  K.width = 300;
  K.height = 225;
  K.cx = 150;
  K.cy = 112;
  K.depth_scale = 1e-4;
  io::DepthImage img;
  img.width = K.width;
  img.height = K.height;
  for (int v = 0; v < K.height; ++v)
    for (int u = 0; u < K.width; ++u)
      img.data.push_back(static_cast<std::uint16_t>(std::lround((0.6 + field(u, v)) / K.depth_scale)));
  return img;
}

// `count` independent Gaussian values of σ `sigma` [m], seeded.
std::vector<double> white_field(std::uint64_t seed, double sigma, std::size_t count) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n(0.0, sigma);
  std::vector<double> white(count);
  for (double& x : white) x = n(rng);
  return white;
}

// White noise: no correlation along rows or columns at any lag, and a quadratic no better
// than a plane (its 3 more parameters take 3 more degrees of freedom, no more).
TEST(DepthStats, WhiteNoiseIsUncorrelatedBothWaysAndPlaneEnough) {
  const std::vector<double> white = white_field(3, 0.001, 300 * 225);
  io::Intrinsics K;
  const io::DepthImage img = wall(K, [&](int u, int v) { return white[v * 300 + u]; });
  const DepthStats s = depth_stats({img}, K);
  for (int l = 0; l < kCorrelationLags; ++l) {
    EXPECT_LT(std::abs(s.correlation_rows[l]), 0.05) << "lag " << l + 1;
    EXPECT_LT(std::abs(s.correlation_cols[l]), 0.05) << "lag " << l + 1;
  }
  EXPECT_LT(s.quad_beats_plane, 0.05);
  ASSERT_EQ(s.scales.size(), 3u);
  for (const DepthStats::Scale& sc : s.scales) {
    EXPECT_GT(sc.windows, 10) << sc.window;
    EXPECT_NEAR(sc.sigma, 0.001, 0.1e-3) << sc.window;
    EXPECT_NEAR(sc.sigma_quad, 0.001, 0.1e-3) << sc.window;
  }
  EXPECT_EQ(s.neighbour_jumps, 0);
  EXPECT_EQ(s.neighbour_pairs, 2L * 300 * 225 - 300 - 225);
}

// Noise averaged over 5 pixels of a row: correlated along rows (the box's 1 - lag/5, less
// what the fits take), not along columns; nothing left at lag 5 and beyond.
TEST(DepthStats, RowCorrelatedNoiseReadsAlongRowsOnly) {
  const std::vector<double> white = white_field(4, 0.002, 304 * 225);
  io::Intrinsics K;
  const io::DepthImage img = wall(K, [&](int u, int v) {
    double sum = 0;
    for (int d = 0; d < 5; ++d) sum += white[v * 304 + u + d];
    return sum / 5;
  });
  const DepthStats s = depth_stats({img}, K);
  EXPECT_GT(s.correlation_rows[0], 0.6);
  EXPECT_GT(s.correlation_rows[1], 0.4);
  // The quadratic's x terms are fitted across all 15 rows of a window and taken from each:
  // of noise this smooth along rows, that shared part reads about 0.1 along columns.
  EXPECT_LT(std::abs(s.correlation_cols[0]), 0.15);
  EXPECT_GT(s.correlation_rows[0] - s.correlation_cols[0], 0.5);
  EXPECT_LT(std::abs(s.correlation_rows[5]), 0.1);
}

// A surface curved within each window (a parabola across every 15 px window's columns,
// 2 mm deep) under faint white noise: a quadratic takes the curve up and a plane does not,
// in every window.
TEST(DepthStats, CurvatureWithinTheWindowIsTakenUpByAQuadratic) {
  const std::vector<double> white = white_field(5, 0.0002, 300 * 225);
  io::Intrinsics K;
  const io::DepthImage img = wall(K, [&](int u, int v) {
    const double x = u % 15 - 7;
    return 4e-5 * x * x + white[v * 300 + u];
  });
  const DepthStats s = depth_stats({img}, K);
  EXPECT_GT(s.quad_beats_plane, 0.9);
  ASSERT_EQ(s.scales.size(), 3u);
  EXPECT_EQ(s.scales[1].window, 15);
  EXPECT_LT(s.scales[1].sigma_quad, 0.5 * s.scales[1].sigma);
  EXPECT_NEAR(s.scales[1].sigma_quad, 0.0002, 0.05e-3);
  ASSERT_EQ(s.sigma_quad_by_angle.size(), s.sigma_by_angle.size());
  int bins = 0;
  for (std::size_t k = 0; k < s.sigma_quad_by_angle.size(); ++k) {
    if (s.sigma_quad_by_angle[k].windows == 0) continue;
    ++bins;
    EXPECT_LT(s.sigma_quad_by_angle[k].sigma, 0.5 * s.sigma_by_angle[k].sigma) << "bin " << k;
  }
  EXPECT_GT(bins, 0);
}

// Quadratic-fit sigma by depth (issue 20): two walls, at 0.65 m with 0.2 mm of white noise
// and at 0.75 m with 0.6 mm, each read in its own depth bin, from the windows sigma_by_depth
// reads; by incidence they pool. Both curve within every window (a parabola 2 mm deep
// across each 15 px window's columns), which a quadratic takes up and a plane does not, so
// the bins read the quadratic's sigma, not the plane's.
TEST(DepthStats, QuadraticSigmaByDepthReadsEachDepthsNoise) {
  const std::vector<double> near_noise = white_field(11, 0.0002, 300 * 225);
  const std::vector<double> far_noise = white_field(12, 0.0006, 300 * 225);
  io::Intrinsics K;
  const auto curve = [](int u) { return 4e-5 * (u % 15 - 7) * (u % 15 - 7); };
  const io::DepthImage near_wall =
      wall(K, [&](int u, int v) { return 0.05 + curve(u) + near_noise[v * 300 + u]; });
  const io::DepthImage far_wall =
      wall(K, [&](int u, int v) { return 0.15 + curve(u) + far_noise[v * 300 + u]; });
  const DepthStats s = depth_stats({near_wall, far_wall}, K);
  ASSERT_EQ(s.sigma_quad_by_depth.size(), s.sigma_by_depth.size());
  for (std::size_t k = 0; k < s.sigma_by_depth.size(); ++k)
    EXPECT_EQ(s.sigma_quad_by_depth[k].windows, s.sigma_by_depth[k].windows) << "bin " << k;
  const auto bin_at = [&](double z) {
    for (const SigmaBin& b : s.sigma_quad_by_depth)
      if (z >= b.lo && z < b.hi) return b;
    return SigmaBin{};
  };
  const SigmaBin near = bin_at(0.65), far = bin_at(0.75);
  ASSERT_GT(near.windows, 100);
  ASSERT_EQ(far.windows, near.windows);
  EXPECT_NEAR(near.sigma, 0.0002, 0.1 * 0.0002);  // 0.1 mm quantization adds 3 um
  EXPECT_NEAR(far.sigma, 0.0006, 0.1 * 0.0006);
  EXPECT_NEAR(far.centre, 0.75, 0.005);
  EXPECT_GT(s.sigma_by_depth[2].sigma, 2 * near.sigma);  // the plane's, 0.6-0.7 m: 0.65 mm
  int by_angle = 0;  // every window once, whatever its incidence
  for (const SigmaBin& b : s.sigma_quad_by_angle) by_angle += b.windows;
  EXPECT_EQ(by_angle, near.windows + far.windows);
}

// The correlation by depth: two walls, at 0.65 m with white noise and at 0.75 m with
// noise averaged over 5 px of a row, each read in its own depth bin (the far one along rows
// only, as RowCorrelatedNoiseReadsAlongRowsOnly reads it alone) from the windows
// sigma_by_depth reads; bins without a window read 0. One bin over every depth pools the
// same sums as correlation_rows and correlation_cols, so it reads them exactly.
TEST(DepthStats, CorrelationByDepthReadsEachDepthsNoise) {
  const std::vector<double> near_noise = white_field(13, 0.001, 300 * 225);
  const std::vector<double> far_noise = white_field(14, 0.002, 304 * 225);
  io::Intrinsics K;
  const io::DepthImage near_wall =
      wall(K, [&](int u, int v) { return 0.05 + near_noise[v * 300 + u]; });
  const io::DepthImage far_wall = wall(K, [&](int u, int v) {
    double sum = 0;
    for (int d = 0; d < 5; ++d) sum += far_noise[v * 304 + u + d];
    return 0.15 + sum / 5;
  });
  const DepthStats s = depth_stats({near_wall, far_wall}, K);
  ASSERT_EQ(s.correlation_by_depth.size(), s.sigma_by_depth.size());
  const DepthStats::CorrelationBin* near = nullptr;
  const DepthStats::CorrelationBin* far = nullptr;
  for (std::size_t k = 0; k < s.sigma_by_depth.size(); ++k) {
    const DepthStats::CorrelationBin& b = s.correlation_by_depth[k];
    EXPECT_EQ(b.lo, s.sigma_by_depth[k].lo);
    EXPECT_EQ(b.hi, s.sigma_by_depth[k].hi);
    EXPECT_EQ(b.windows, s.sigma_by_depth[k].windows) << "bin " << k;
    if (b.lo <= 0.65 && 0.65 < b.hi) near = &b;
    if (b.lo <= 0.75 && 0.75 < b.hi) far = &b;
    if (b.windows != 0) continue;
    for (int l = 0; l < kCorrelationLags; ++l) {
      EXPECT_EQ(b.rows[l], 0.0) << "bin " << k;
      EXPECT_EQ(b.cols[l], 0.0) << "bin " << k;
    }
  }
  ASSERT_NE(near, nullptr);
  ASSERT_NE(far, nullptr);
  ASSERT_GT(near->windows, 100);
  ASSERT_EQ(far->windows, near->windows);
  for (int l = 0; l < kCorrelationLags; ++l) {
    EXPECT_LT(std::abs(near->rows[l]), 0.05) << "lag " << l + 1;
    EXPECT_LT(std::abs(near->cols[l]), 0.05) << "lag " << l + 1;
  }
  EXPECT_GT(far->rows[0], 0.6);
  EXPECT_GT(far->rows[1], 0.4);
  EXPECT_LT(std::abs(far->cols[0]), 0.15);
  // Pooled, the near wall's white noise dilutes the far wall's correlation.
  EXPECT_LT(s.correlation_rows[0], far->rows[0] - 0.2);

  DepthStatsParams one_bin;
  one_bin.depth_edges = {0.0, 10.0};
  const DepthStats pooled = depth_stats({near_wall, far_wall}, K, one_bin);
  ASSERT_EQ(pooled.correlation_by_depth.size(), 1u);
  EXPECT_EQ(pooled.correlation_by_depth[0].windows, 2 * near->windows);
  for (int l = 0; l < kCorrelationLags; ++l) {
    EXPECT_EQ(pooled.correlation_by_depth[0].rows[l], pooled.correlation_rows[l])
        << "lag " << l + 1;
    EXPECT_EQ(pooled.correlation_by_depth[0].cols[l], pooled.correlation_cols[l])
        << "lag " << l + 1;
  }
}

// Valid neighbours across a 100 mm step are jumps, one per row; an invalid column between
// the two sides (what a real camera leaves) makes none.
TEST(DepthStats, NeighbourJumpsCountValidPairsAcrossAStep) {
  io::Intrinsics K;
  const io::DepthImage step = wall(K, [](int u, int) { return u < 150 ? 0.0 : 0.1; });
  const DepthStats s = depth_stats({step}, K);
  EXPECT_EQ(s.neighbour_jumps, 225);
  io::DepthImage gap = step;
  for (int v = 0; v < 225; ++v) gap.data[static_cast<std::size_t>(v) * 300 + 150] = 0;
  const DepthStats g = depth_stats({gap}, K);
  EXPECT_EQ(g.neighbour_jumps, 0);
  EXPECT_EQ(g.neighbour_pairs, s.neighbour_pairs - 2 * 225 - 224);
}

// The two flying-pixel rulers on one hand-made band per row, 0.6 m left of it and 0.7 m
// right: u = 148, 149 near | 150, 151 invalid | 152 at 0.65 m (flying, half-way) | 153,
// 154 invalid | 155 at 0.6 m (a fragment of the near surface) | 156 invalid | 157, 158 far.
// Beside the bands (2 px either side of each invalid run, from 148 to 158): 148, 149, 152,
// 155, 157, 158, one flying: 1/6. The old ruler: the stable sides 149 and 157 and both
// fragments, one flying: 1/4.
TEST(DepthStats, FlyingPixelsBesideTheBandsCountEachPixelOnce) {
  io::Intrinsics K;
  io::DepthImage img = wall(K, [](int u, int) { return u < 150 ? 0.0 : 0.1; });
  const auto at = [&](int u, int v) -> std::uint16_t& {
    return img.data[static_cast<std::size_t>(v) * 300 + static_cast<std::size_t>(u)];
  };
  for (int v = 0; v < 225; ++v) {
    for (const int u : {150, 151, 153, 154, 156}) at(u, v) = 0;
    at(152, v) = static_cast<std::uint16_t>(std::lround(0.65 / K.depth_scale));
    at(155, v) = static_cast<std::uint16_t>(std::lround(0.6 / K.depth_scale));
  }
  const DepthStats s = depth_stats({img}, K);
  EXPECT_EQ(s.band_side_pixels, 6 * 225);
  EXPECT_EQ(s.band_side_flying, 225);
  EXPECT_DOUBLE_EQ(s.flying_band_rate, 1.0 / 6);
  EXPECT_EQ(s.band_neighbours, 4 * 225);
  EXPECT_DOUBLE_EQ(s.flying_rate, 0.25);
}

// Holes of a re-render, counted where the camera saw a surface. The camera's frame: a
// wall with one 2 x 2 hole at (60, 60) and an invalid strip (u 200-209, every row: not a
// hole, it reaches the border). The re-render fills the strip and has three 2 x 2 holes:
// on the camera's hole, on the wall the camera saw, and on the strip's fill. Read with the
// camera's frame as `seen`, the last is on no surface the camera saw and is not counted;
// on its own, all three are. Each pixel of a hole and of its 2 px ring must be seen: one
// astride the strip's edge, or beside it, is not counted either. Draws pair with frames
// as rerender_surfaces orders them (draw-major).
TEST(DepthStats, ReRenderedHolesCountWhereTheCameraSawASurface) {
  io::Intrinsics K;
  const io::DepthImage flat = wall(K, [](int, int) { return 0.0; });
  const auto hole = [&](io::DepthImage& img, int u0, int v0) {
    for (int v = v0; v < v0 + 2; ++v)
      for (int u = u0; u < u0 + 2; ++u) img.data[static_cast<std::size_t>(v) * 300 + u] = 0;
  };
  io::DepthImage camera = flat;
  hole(camera, 60, 60);
  for (int v = 0; v < 225; ++v)
    for (int u = 200; u < 210; ++u) camera.data[static_cast<std::size_t>(v) * 300 + u] = 0;
  io::DepthImage rendered = flat;
  hole(rendered, 60, 60);
  hole(rendered, 100, 150);
  hole(rendered, 204, 100);
  const std::vector<io::DepthImage> seen{camera};
  EXPECT_EQ(depth_stats({camera}, K).holes_per_frame, 1.0);
  EXPECT_EQ(depth_stats({rendered}, K).holes_per_frame, 3.0);
  EXPECT_EQ(depth_stats({rendered}, K, {}, &seen).holes_per_frame, 2.0);
  EXPECT_EQ(depth_stats({rendered, rendered}, K, {}, &seen).holes_per_frame, 2.0);
  io::DepthImage astride = flat;
  hole(astride, 199, 100);
  EXPECT_EQ(depth_stats({astride}, K).holes_per_frame, 1.0);
  EXPECT_EQ(depth_stats({astride}, K, {}, &seen).holes_per_frame, 0.0);
  // A hole 1 px from the strip lies on seen pixels, but its 2 px ring does not: the camera
  // could not have counted a hole there, so the re-render's is not counted either.
  io::DepthImage beside = flat;
  hole(beside, 197, 100);
  EXPECT_EQ(depth_stats({beside}, K).holes_per_frame, 1.0);
  EXPECT_EQ(depth_stats({beside}, K, {}, &seen).holes_per_frame, 0.0);
  // An invalid region the camera does not count as a hole (40 x 40 px, over max_hole_px)
  // is not a surface it saw: a re-rendered hole inside it is not counted.
  io::DepthImage big = camera;
  for (int v = 20; v < 60; ++v)
    for (int u = 100; u < 140; ++u) big.data[static_cast<std::size_t>(v) * 300 + u] = 0;
  io::DepthImage inside = flat;
  hole(inside, 118, 38);
  const std::vector<io::DepthImage> seen_big{big};
  EXPECT_EQ(depth_stats({big}, K).holes_per_frame, 1.0);
  EXPECT_EQ(depth_stats({inside}, K).holes_per_frame, 1.0);
  EXPECT_EQ(depth_stats({inside}, K, {}, &seen_big).holes_per_frame, 0.0);
  // Draw-major pairing: images (on strip, none, on strip, none) of the frames (camera,
  // flat) pair the holes with the camera's frame (none counted); paired frame-major (0, 0,
  // 1, 1) the third would pair with the flat frame and count.
  io::DepthImage on_strip = flat;
  hole(on_strip, 204, 100);
  const std::vector<io::DepthImage> camera_and_flat{camera, flat};
  EXPECT_EQ(depth_stats({on_strip, flat, on_strip, flat}, K, {}, &camera_and_flat).holes_per_frame,
            0.0);
  EXPECT_EQ(depth_stats({flat, on_strip, flat, on_strip}, K, {}, &camera_and_flat).holes_per_frame,
            0.5);
  // The rest of the statistics do not read `seen`.
  EXPECT_EQ(depth_stats({rendered}, K, {}, &seen).windows, depth_stats({rendered}, K).windows);
  const std::vector<io::DepthImage> none;
  EXPECT_EQ(test::error_of<std::invalid_argument>(
                [&] { (void)depth_stats({rendered}, K, {}, &none); }),
            "depth statistics: no seen frame");
  const std::vector<io::DepthImage> two{camera, camera};
  EXPECT_EQ(test::error_of<std::invalid_argument>(
                [&] { (void)depth_stats({rendered}, K, {}, &two); }),
            "depth statistics: 1 images are not a whole number of draws of 2 seen frames");
  io::DepthImage narrow = camera;
  narrow.width = 150;
  narrow.data.resize(150 * 225);
  const std::vector<io::DepthImage> wrong{narrow};
  EXPECT_EQ(test::error_of<std::invalid_argument>(
                [&] { (void)depth_stats({rendered}, K, {}, &wrong); }),
            "seen frame 0 is 150x225, the intrinsics say 300x225");
}

TEST(DepthStats, BadInputIsNamed) {
  io::Intrinsics K;
  std::vector<io::DepthImage> frames = real_frames(K);
  auto error_of = [&](const std::vector<io::DepthImage>& f, const io::Intrinsics& k) {
    try {
      (void)depth_stats(f, k);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(error_of({}, K).find("no frames"), std::string::npos);
  io::DepthImage empty = frames[0];
  std::fill(empty.data.begin(), empty.data.end(), 0);
  EXPECT_NE(error_of({empty}, K).find("no valid pixel"), std::string::npos);
  io::Intrinsics wrong = K;
  wrong.width = 320;
  EXPECT_NE(error_of({frames[0]}, wrong).find("frame 0 is 640x480, the intrinsics say 320x480"),
            std::string::npos);
  // A recording too small to estimate from: a frame with a few valid pixels only.
  io::DepthImage sparse = empty;
  for (std::size_t i = 0; i < sparse.data.size(); i += 97) sparse.data[i] = 5000;
  EXPECT_NE(error_of({sparse}, K).find("need at least 10"), std::string::npos);
  DepthStatsParams p;
  p.window = 3;
  EXPECT_THROW(p.validate(), std::invalid_argument);
  p = {};
  p.scale_windows = {9, 4};
  EXPECT_EQ(test::error_of([&] { p.validate(); }),
            "DepthStatsParams.scale_windows: each must be >= 5 px");
}

}  // namespace
}  // namespace linksight::sim
