// Episodes of every shipped scene, short, with sanity bands; `--set` overrides and the
// tracker keys of scene files.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "linksight/io/error.hpp"
#include "linksight/sim/episode.hpp"
#include "test_support.hpp"

namespace linksight::sim {
namespace {

const std::filesystem::path kScenes = LINKSIGHT_SCENE_DIR;
const char* const kShipped[] = {"default",           "static",           "bend_push",
                                "base_sweep",        "occluder_pass",    "self_occlusion",
                                "clutter",           "fast_motion",      "robustness_static",
                                "robustness_moving"};

// The link is tracked to within a few centimetres while nothing disturbs it. The SOM
// puts nodes at the mean of the visible front surface, 2/3 of a ball radius (10 mm)
// in front of the true centre, so the band is not tighter than that.
constexpr double kQuietErrorBand = 0.025;  // [m]

TEST(Episode, EveryShippedSceneLoadsAndRunsItsFirstFrames) {
  for (const char* name : kShipped) {
    SCOPED_TRACE(name);
    const Scene scene = load_scene(kScenes / (std::string(name) + ".yaml"));
    EpisodeOptions o;
    o.frames = 3;
    o.modes = {parse_mode("paper"), parse_mode("accelerated-som")};
    Episode e(scene, o);
    ASSERT_EQ(e.frames(), 3);
    for (int f = 0; f < 3; ++f) {
      const EpisodeFrame& fr = e.step();
      EXPECT_EQ(fr.frame, f);
      EXPECT_GT(fr.cloud->size(), 500u);
      ASSERT_EQ(fr.scores.size(), 2u);
      EXPECT_FALSE(fr.results[0].lost);
      EXPECT_TRUE(std::isfinite(fr.scores[0].mean_err));
    }
    const auto s = e.summaries();
    ASSERT_EQ(s.size(), 2u);
    EXPECT_EQ(s[0].frames, 3);
    // Not clutter: depth segmentation keeps mugs and clutter. Not self_occlusion: with the
    // sr300 preset's projector on the image-left, the bent tip lies in the link's own
    // projector shadow, its node's neighbourhood empties on frame 1, and the paper's
    // re-initialization slips one component (docs/robustness.md): 44 mm, held below.
    const std::string n(name);
    if (n != "clutter" && n != "self_occlusion") {
      EXPECT_LT(s[0].node_err.max, kQuietErrorBand);
    }
    if (n == "self_occlusion") {
      EXPECT_LT(s[0].node_err.max, test::kSlipBand);
      EXPECT_EQ(s[0].swaps, 0);
    }
  }
}

// chain-fit from the first frame of every shipped scene with the default camera: within
// kChainFitStartBand over the first kChainFitStartFrames frames. A fresh fit could settle a
// whole component along the chain (every node about one 45 mm pitch off): on
// self_occlusion under the two-scale sr300 camera it did, 45 mm from frame 0 (every
// node misassigned), until the fit moved by one component each way competed with it
// (update_chain_fit.cpp, best_of_shifts). Measured 2026-11-28 (worst frame over the first
// five): 1.1-1.8 mm in every scene, self_occlusion 1.76 mm. With the base prior
// (tracker.base_prior, the scene's error drawn) the anchor on ball 0 keeps the start on
// the link by itself: measured 2026-11-29, 1.06-1.83 mm, self_occlusion 1.67 mm, the same
// with and without the moved fits (they never win there; without the prior, 45.6 mm).
constexpr int kChainFitStartFrames = 5;
constexpr double kChainFitStartBand = 0.005;  // [m]: the scoring's recovery threshold

// Runs the first kChainFitStartFrames frames of every shipped scene with chain-fit alone and
// checks that it is on the link: within kChainFitStartBand, nothing lost or misassigned.
void ExpectChainFitStartsOnTheLink(bool base_prior) {
  for (const char* name : kShipped) {
    SCOPED_TRACE(name);
    Scene scene = load_scene(kScenes / (std::string(name) + ".yaml"));
    if (base_prior) scene.tracker.base_prior.enabled = true;
    EpisodeOptions o;
    o.frames = kChainFitStartFrames;
    o.modes = {parse_mode("chain-fit")};
    Episode e(scene, o);
    while (e.done() < e.frames()) (void)e.step();
    const auto s = e.summaries();
    ASSERT_EQ(s.size(), 1u);
    EXPECT_EQ(s[0].lost_frames, 0);  // a lost frame would leave node_err.max
    EXPECT_LT(s[0].node_err.max, kChainFitStartBand);
    EXPECT_EQ(s[0].misassigned, 0);  // one node a pitch off adds only 4 mm to a frame's mean
    EXPECT_EQ(s[0].swaps, 0);
  }
}

TEST(Episode, ChainFitStartsOnTheLinkInEveryShippedScene) { ExpectChainFitStartsOnTheLink(false); }

TEST(Episode, ChainFitStartsOnTheLinkWithABasePrior) { ExpectChainFitStartsOnTheLink(true); }

TEST(Episode, StaticPaperErrorIsStableOverTime) {
  const Scene scene = load_scene(kScenes / "static.yaml");
  EpisodeOptions o;
  o.frames = 30;
  Episode e(scene, o);
  double lo = 1, hi = 0;
  while (e.done() < e.frames()) {
    const double err = e.step().scores[0].mean_err;
    lo = std::min(lo, err);
    hi = std::max(hi, err);
  }
  EXPECT_LT(hi, kQuietErrorBand);
  EXPECT_LT(hi - lo, 0.002) << "a resting link at nominal noise: the error must not drift";
  EXPECT_EQ(e.summaries()[0].reinit_count, 0);
}

// The surface bias and its correction on rendered SR300 frames of a resting link. Paper
// mode's nodes sit on the seen surface, about 2/3 r = 10 mm in front of the centres
// (measured over 150 frames: 12.1 mm mean node error, the tip node 22 mm of it);
// paper-centred moves them back and reaches 3.9 mm mean, 4.2 mm worst frame. Its band
// is the 5 mm recovery threshold of the scoring, which it must reach to count as
// recovered at all; paper mode must stay above it, or the correction is not needed.
TEST(Episode, PaperCentredRemovesTheSurfaceBias) {
  const Scene scene = load_scene(kScenes / "static.yaml");
  EpisodeOptions o;
  o.frames = 30;
  o.modes = {parse_mode("paper"), parse_mode("paper-centred")};
  Episode e(scene, o);
  while (e.done() < e.frames()) (void)e.step();
  const auto s = e.summaries();
  EXPECT_GT(s[0].node_err.mean, 0.010);
  EXPECT_LT(s[1].node_err.max, o.score.recovered_below);
  EXPECT_GT(s[0].node_err.mean - s[1].node_err.mean, 0.006);
  EXPECT_LT(s[1].mean_sdf, s[0].mean_sdf);
}

// The paper's claim (Sec. IV.C): re-initialization recovers from motion that breaks
// association; the accelerated SOM, without it, does not. The whole scene (5 s, three
// jumps).
TEST(Episode, FastMotionBaselineNeverBeatsPaperMode) {
  const Scene scene = load_scene(kScenes / "fast_motion.yaml");
  EpisodeOptions o;
  o.modes = {parse_mode("paper"), parse_mode("accelerated-som")};
  Episode e(scene, o);
  bool jumped = false;
  while (e.done() < e.frames()) {
    const EpisodeFrame& f = e.step();
    jumped = jumped || f.truth_motion > o.score.fast_motion_from;
    EXPECT_LE(f.scores[0].mean_err, f.scores[1].mean_err + 1e-4) << "frame " << f.frame;
  }
  EXPECT_TRUE(jumped);
  const auto s = e.summaries();
  ASSERT_FALSE(s[0].events.empty());
  EXPECT_EQ(s[0].events[0].kind, Event::Kind::fast_motion);
  EXPECT_GE(s[0].reinit_count, 1);
  EXPECT_LT(s[0].node_err.max, 0.05);
  EXPECT_GT(s[1].node_err.max, 0.05) << "the jump was meant to break the baseline";
}

TEST(Episode, SameScoresForAnyThreadCount) {
  const Scene scene = load_scene(kScenes / "occluder_pass.yaml");
  EpisodeOptions o;
  o.frames = 4;
  auto errors = [&](int threads) {
    o.threads = threads;
    Episode e(scene, o);
    std::vector<double> v;
    while (e.done() < e.frames()) v.push_back(e.step().scores[0].mean_err);
    return v;
  };
  EXPECT_EQ(errors(1), errors(2));
}

// A recorded episode's physics, replayed by another episode of the same world with other
// noise and a board (what a sweep's cells share): every frame's truth, track and score is
// what that episode gives running its own world, bit for bit; a replay too short or at
// another frame rate is refused.
TEST(Episode, ReplayedPhysicsGivesTheSameFramesAsTheWorld) {
  const Scene recorded = load_scene(kScenes / "default.yaml");
  const Scene scene = load_scene(kScenes / "default.yaml",
                                 {"noise.scale=2", "occlusion.fraction=0.3", "seed=9"});
  EpisodeOptions o;
  o.frames = 12;
  o.modes = {parse_mode("chain-fit"), parse_mode("paper")};
  o.record = true;
  Episode first(recorded, o);
  EXPECT_EQ(first.recording(), nullptr);  // not before the last frame
  while (first.done() < first.frames()) (void)first.step();
  const std::shared_ptr<const PhysicsRecording> physics = first.recording();
  ASSERT_NE(physics, nullptr);
  ASSERT_EQ(physics->frames.size(), 12u);
  EXPECT_EQ(physics->fps, recorded.camera.fps);

  o.record = false;
  EpisodeOptions replay = o;
  replay.replay = physics;
  Episode own(scene, o), replayed(scene, replay);
  int moved = 0;
  while (own.done() < own.frames()) {
    const EpisodeFrame& a = own.step();
    const Truth truth = a.truth;
    const std::vector<FrameResult> results = a.results;
    const std::vector<FrameScore> scores = a.scores;
    const EpisodeFrame& b = replayed.step();
    SCOPED_TRACE("frame " + std::to_string(b.frame));
    EXPECT_EQ(b.truth.t, truth.t);
    ASSERT_EQ(b.truth.nodes_W.size(), truth.nodes_W.size());
    for (std::size_t j = 0; j < truth.nodes_W.size(); ++j)
      EXPECT_EQ(b.truth.nodes_W[j], truth.nodes_W[j]);
    ASSERT_EQ(b.truth.X_WK.size(), truth.X_WK.size());
    for (std::size_t j = 0; j < truth.X_WK.size(); ++j)
      EXPECT_EQ(b.truth.X_WK[j].matrix(), truth.X_WK[j].matrix());
    ASSERT_EQ(b.results.size(), results.size());
    for (std::size_t k = 0; k < results.size(); ++k) {
      EXPECT_EQ(b.results[k].nodes, results[k].nodes);
      EXPECT_EQ(b.scores[k].mean_err, scores[k].mean_err);
    }
    moved += b.truth_motion > 0;
  }
  EXPECT_GT(moved, 0);  // the pusher moves the link: the frames are not all one truth
  EXPECT_EQ(replayed.recording(), physics);

  EpisodeOptions longer = replay;
  longer.frames = 13;
  EXPECT_EQ(test::error_of([&] { Episode e(scene, longer); }),
            "episode: the physics recording has 12 frames at 30 fps; this episode needs 13 at 30");
  auto other_chain = std::make_shared<PhysicsRecording>(*physics);
  for (Truth& t : other_chain->frames) t.nodes_W.resize(5);
  EpisodeOptions other = replay;
  other.replay = other_chain;
  EXPECT_EQ(test::error_of([&] { Episode e(scene, other); }),
            "episode: the physics recording has a chain of 5 nodes; this scene's has 12");
  const Scene faster = load_scene(kScenes / "default.yaml", {"camera.fps=60"});
  EXPECT_EQ(test::error_of([&] { Episode e(faster, replay); }),
            "episode: the physics recording has 12 frames at 30 fps; this episode needs 12 at 60");
}

// tracker.base_prior: each frame's trackers get the true base pose (ball 0's centre at its
// origin) times one error drawn per episode from the seed, about σ in size.
TEST(Episode, BasePriorIsTheTrueBasePoseWithOneSeededErrorPerEpisode) {
  Scene scene = load_scene(kScenes / "base_sweep.yaml");
  EpisodeOptions o;
  o.frames = 3;
  o.modes = {parse_mode("chain-fit")};
  {
    Episode e(scene, o);
    EXPECT_FALSE(e.step().base_prior_C.has_value());
  }
  scene.tracker.base_prior.enabled = true;
  const Eigen::Isometry3d error = base_prior_error(scene);
  const double sigma_m = scene.tracker.base_prior.sigma_m;
  const double sigma_rad = scene.tracker.base_prior.sigma_rad;
  EXPECT_GT(error.translation().norm(), 0.0);
  EXPECT_LT(error.translation().norm(), 5 * sigma_m);
  EXPECT_LT(Eigen::AngleAxisd(error.linear()).angle(), 5 * sigma_rad);
  Scene other = scene;
  other.seed += 1;
  EXPECT_FALSE(base_prior_error(other).isApprox(error));
  EXPECT_TRUE(base_prior_error(scene).isApprox(error, 0.0));  // same seed, same bits
  const Eigen::Isometry3d X_CW = scene.camera.X_WC.inverse();
  Episode e(scene, o);
  for (int f = 0; f < 3; ++f) {
    const EpisodeFrame& fr = e.step();
    ASSERT_TRUE(fr.base_prior_C.has_value());
    EXPECT_NEAR((fr.truth.X_WB.translation() - fr.truth.nodes_W[0]).norm(), 0.0, 1e-6);
    const Eigen::Isometry3d expected = X_CW * fr.truth.X_WB * error;
    EXPECT_TRUE(fr.base_prior_C->isApprox(expected, 1e-12));
    // (sr300's two-scale noise: 1.10-1.12 mm measured; the band was 1 mm with sr300-one-field)
    EXPECT_LT(fr.scores[0].mean_err, 0.0015);
  }
}

// chain_only_images renders the chain's box only, yet every cloud, track and score is
// the whole-frame episode's: leakage on (its margin must be rendered too), the hand in
// front of the link, and whole_frames rendered whole. chain-fit and paper compared;
// chain-fit without its free-space evidence (which reads the whole depth image: with it,
// every frame is rendered whole, below).
TEST(Episode, ChainOnlyImagesGiveTheSameCloudsAndScores) {
  // leakage_px reaches past the chain box's own jitter margin, so the margin must be added.
  // The hand's path is the scene's moved 1.6 s earlier (its first waypoint is where it was
  // at 1.6 s), so that it is over the middle at 0.2 s rather than 1.8 s: 10 frames a run,
  // not 58 (this test runs under the sanitizers in CI).
  Scene scene = load_scene(kScenes / "occluder_pass.yaml",
                           {"segmentation.leakage=0.5", "segmentation.leakage_px=15",
                            "tracker.chain_fit.free_space_below=0",
                            "occluders[0].path.waypoints=["
                            "{t_s: 0.0, position_m: [0.0525, -0.3, 0.47]},"
                            "{t_s: 0.9, position_m: [0.30, -0.3, 0.47]},"
                            "{t_s: 1.4, position_m: [0.30, -0.3, 0.90]}]"});
  struct Run {
    std::vector<std::vector<float>> clouds;
    std::vector<double> errors, occluded;
    std::vector<bool> whole;
  };
  auto run = [&](bool chain_only, double from_s) {
    EpisodeOptions o;
    o.frames = static_cast<int>(std::lround(from_s * scene.camera.fps)) + 4;
    o.chain_only_images = chain_only;
    o.whole_frames = {o.frames - 2};
    o.modes = {parse_mode("chain-fit"), parse_mode("paper")};
    Episode e(scene, o);
    Run r;
    while (e.done() < e.frames()) {
      const EpisodeFrame& f = e.step();
      if (f.t < from_s - 1e-9) continue;
      r.clouds.push_back(f.cloud->xyz);
      r.errors.push_back(f.scores[0].mean_err);
      r.errors.push_back(f.scores[1].mean_err);
      r.occluded.push_back(f.image->link_occluded_fraction);
      r.whole.push_back(f.image->rendered == PixelBox{0, f.image->width - 1, 0, f.image->height - 1});
    }
    return r;
  };
  const Run a = run(false, 0.2);  // the hand over the middle
  const Run b = run(true, 0.2);
  ASSERT_EQ(a.clouds.size(), 4u);
  EXPECT_EQ(a.clouds, b.clouds);
  EXPECT_EQ(a.errors, b.errors);
  EXPECT_EQ(a.occluded, b.occluded);
  EXPECT_GT(a.occluded[0], 0.02) << "the hand was meant to cover part of the link";
  EXPECT_EQ(a.whole, (std::vector<bool>{true, true, true, true}));
  EXPECT_EQ(b.whole, (std::vector<bool>{false, false, true, false}));
  // With the free-space evidence, chain-fit reads the depth image wherever a hidden ball
  // is held: every frame whole, the same scores.
  scene.tracker.policy.chain_fit.free_space_below = 10;
  const Run c = run(false, 0.2);
  const Run d = run(true, 0.2);
  EXPECT_EQ(c.errors, d.errors);
  EXPECT_EQ(d.whole, (std::vector<bool>{true, true, true, true}));
}

TEST(Episode, BadOptionsAreNamed) {
  const Scene scene = load_scene(kScenes / "static.yaml");
  EpisodeOptions o;
  o.modes = {parse_mode("paper"), parse_mode("paper")};
  try {
    Episode e(scene, o);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("paper given twice"), std::string::npos) << e.what();
  }
  o = {};
  o.frames = -1;
  EXPECT_THROW(Episode(scene, o), std::invalid_argument);
}

class Overrides : public ::testing::Test {
 protected:
  std::filesystem::path dir =
      test::scratch_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
  std::string error_of(const std::filesystem::path& scene, std::vector<std::string> set) {
    try {
      (void)load_scene(scene, set);
    } catch (const io::InputError& e) {
      return e.what();
    }
    return "no error";
  }
};

TEST_F(Overrides, SetReachesScalarsNestedKeysListsAndVectors) {
  const Scene s = load_scene(kScenes / "occluder_pass.yaml",
                             {"camera.fps=60", "noise.axial.a_m=0.001", "seed=99",
                              "occluders[1].reflectance=0.25",
                              "occluders[1].half_extents_m=[0.1, 0.01, 0.05]",
                              "tracker.mode=accelerated-som", "tracker.iterations=6",
                              "world.gravity=false"});
  EXPECT_EQ(s.camera.fps, 60);
  EXPECT_EQ(s.noise.axial.a, 0.001);
  EXPECT_EQ(s.seed, 99u);
  EXPECT_EQ(s.occluders[1].reflectance, 0.25);
  EXPECT_EQ(s.occluders[1].shape.half_extents, Eigen::Vector3d(0.1, 0.01, 0.05));
  EXPECT_EQ(s.tracker.mode, parse_mode("accelerated-som"));
  EXPECT_EQ(s.tracker.iterations, 6);
  EXPECT_FALSE(s.world.gravity);
  // The file alone is unchanged.
  const Scene plain = load_scene(kScenes / "occluder_pass.yaml");
  EXPECT_EQ(plain.camera.fps, 30);
  EXPECT_EQ(plain.tracker.mode, parse_mode("chain-fit"));  // the default (issue 17)
  // A key the file does not have is created.
  EXPECT_EQ(load_scene(kScenes / "static.yaml", {"segmentation.leakage=0.3"}).segmentation.leakage,
            0.3);
}

TEST_F(Overrides, NoiseScaleMultipliesTheRandomTermsOnly) {
  const Scene nominal = load_scene(kScenes / "static.yaml");
  const Scene doubled = load_scene(kScenes / "static.yaml", {"noise.scale=2"});
  EXPECT_DOUBLE_EQ(doubled.noise.axial.a, 2 * nominal.noise.axial.a);
  EXPECT_DOUBLE_EQ(doubled.noise.axial.c, 2 * nominal.noise.axial.c);
  EXPECT_DOUBLE_EQ(doubled.noise.axial.k_theta, 2 * nominal.noise.axial.k_theta);
  EXPECT_DOUBLE_EQ(doubled.noise.lateral.sigma_px, 2 * nominal.noise.lateral.sigma_px);
  EXPECT_EQ(doubled.noise.edges.p_flying, nominal.noise.edges.p_flying);
  EXPECT_EQ(doubled.noise.dropouts.hole_rate, nominal.noise.dropouts.hole_rate);
  EXPECT_GT(nominal.noise.axial.a, 0.0);
  EXPECT_EQ(load_scene(kScenes / "static.yaml", {"noise.scale=0"}).noise.axial.a, 0.0);
  EXPECT_NE(error_of(kScenes / "static.yaml", {"noise.scale=-1"}).find("noise.scale"),
            std::string::npos);
}

TEST_F(Overrides, BadOverridesNameTheSetAndTheKey) {
  const auto scene = kScenes / "static.yaml";
  auto has = [](const std::string& what, const std::string& needle) {
    return what.find(needle) != std::string::npos;
  };
  std::string e = error_of(scene, {"camera.fps=fast"});
  EXPECT_TRUE(has(e, "--set camera.fps=fast: camera.fps: expected a number")) << e;
  e = error_of(scene, {"camera.fsp=30"});
  EXPECT_TRUE(has(e, "--set camera.fsp=30: camera.fsp: unknown key")) << e;
  e = error_of(scene, {"tracker.mode=fastest"});
  EXPECT_TRUE(has(e, "--set tracker.mode=fastest: tracker.mode: unknown mode 'fastest' (expected chain-fit, paper, ")) << e;
  e = error_of(scene, {"occluders[0].reflectance=1"});
  EXPECT_TRUE(has(e, "no element 0")) << e;
  e = error_of(scene, {"camera.fps"});
  EXPECT_TRUE(has(e, "expected key.path=value")) << e;
  e = error_of(scene, {"camera.fps=[1"});
  EXPECT_TRUE(has(e, "not valid YAML")) << e;
  e = error_of(scene, {"tracker.base_prior.sigma_m=0"});
  EXPECT_TRUE(has(e, "tracker.base_prior.sigma_m = 0: must be in [1e-06, 1]")) << e;
  e = error_of(scene, {"tracker.base_prior.enabled=maybe"});
  EXPECT_TRUE(has(e, "tracker.base_prior.enabled")) << e;
  e = error_of(scene, {"tracker.iterations=0"});
  EXPECT_TRUE(has(e, "--set tracker.iterations=0: tracker.iterations = 0: must be in [1, 1000]")) << e;
}

TEST_F(Overrides, TrackerKeysInAFileNameTheirLine) {
  const auto p = dir / "scene.yaml";
  std::ofstream(p) << "duration_s: 1\ntracker:\n  mode: paper\n  backend: cuda\n";
  const std::string e = error_of(p, {});
  EXPECT_NE(e.find(":4: tracker.backend: unknown backend 'cuda' (expected serial, openmp or opencl)"),
            std::string::npos)
      << e;
  std::ofstream(p) << "tracker:\n  iterations: 7\n  init: paper\n  som_init: random-sample\n";
  const Scene s = load_scene(p);
  EXPECT_EQ(s.tracker.iterations, 7);
  EXPECT_EQ(s.tracker.policy.lsq_init.method, InitMethod::paper);
  EXPECT_EQ(s.tracker.policy.som_init.method, SomInit::random_sample);
  EXPECT_EQ(s.tracker.nodes, s.chain.geometry.count + 1);
}

// Issue 17: the slip case of docs/robustness.md. A board over 5% of the tip of the moving
// link, no noise: paper mode's LSQ re-initialization lays the nodes out along what is seen
// and slips by one component (its known failure, kept visible here); chain-fit keeps
// every node on its own ball, holds within kChainFitWorstBand while the board is there
// and is back within 1 mm of its error before it within 3 frames after it leaves.
TEST(Episode, ChainFitDoesNotSlipUnderATipBoard) {
  constexpr double kChainFitWorstBand = 0.005;  // [m]: issue 17's still-link target
  constexpr double kRecoveredMargin = 0.001;    // [m]
  constexpr int kRecoverFrames = 3;
  const Scene scene = load_scene(kScenes / "robustness_moving.yaml",
                                 {"occlusion.at=tip", "occlusion.fraction=0.05",
                                  "noise.scale=0"});
  EpisodeOptions o;
  o.modes = {parse_mode("chain-fit"), parse_mode("paper")};
  Episode e(scene, o);
  int misassigned[2] = {0, 0};
  double worst = 0, before = 0;
  int before_frames = 0, board_frames = 0, end_frame = -1, recover = -1;
  while (e.done() < e.frames()) {
    const EpisodeFrame& f = e.step();
    for (int k = 0; k < 2; ++k) misassigned[k] += f.scores[k].misassigned;
    const double err = f.scores[0].mean_err;
    if (f.t < scene.occlusion.from_s - 1e-9) {
      before += err;
      ++before_frames;
    } else if (f.t < scene.occlusion.to_s - 1e-9) {
      worst = std::max(worst, err);
      board_frames += f.image->link_occluded_fraction > 0;
    } else {
      if (end_frame < 0) end_frame = f.frame;
      if (recover < 0 && err <= before / before_frames + kRecoveredMargin)
        recover = f.frame - end_frame;
    }
  }
  ASSERT_GT(board_frames, 10);  // the board did hide part of the link
  EXPECT_EQ(misassigned[0], 0) << "chain-fit slipped";
  EXPECT_LT(worst, kChainFitWorstBand);
  EXPECT_GE(recover, 0);
  EXPECT_LE(recover, kRecoverFrames);
  EXPECT_GT(misassigned[1], 0) << "paper mode no longer slips here: docs/robustness.md is stale";
}

}  // namespace
}  // namespace linksight::sim
