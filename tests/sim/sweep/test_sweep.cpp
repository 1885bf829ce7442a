// Sweeps: grid enumeration, per-cell seeds, shards, merge and its completeness check.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "linksight/io/error.hpp"
#include "linksight/sim/episode.hpp"
#include "linksight/sim/sweep.hpp"
#include "test_support.hpp"

namespace linksight::sim {
namespace {

namespace fs = std::filesystem;
const fs::path kScenes = LINKSIGHT_SCENE_DIR;

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// A tiny grid: 3 x 2 cells of 2 frames, two modes per cell.
SweepSpec tiny() {
  SweepSpec s;
  s.scene = kScenes / "static.yaml";
  s.axes = {parse_axis("noise.scale=0,1,2"), parse_axis("tracker.iterations=2,4")};
  s.modes = {parse_mode("paper"), parse_mode("paper-centred")};
  s.frames = 2;
  return s;
}

class Sweep : public ::testing::Test {
 protected:
  fs::path dir =
      test::scratch_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
  // Runs shard i of n into `d` as the CLI does.
  static void run_shard(const fs::path& d, const SweepSpec& spec, int i, int n) {
    write_manifest(d, spec);
    std::vector<SweepRow> rows;
    for (const std::size_t c : shard_cells(spec, i, n))
      for (SweepRow& r : run_cell(spec, c, 0)) rows.push_back(std::move(r));
    write_shard(d, spec, i, n, rows);
  }
};

TEST(SweepAxis, ParsesAndNamesBadArguments) {
  const SweepAxis a = parse_axis("noise.scale= 0, 0.5,1");
  EXPECT_EQ(a.key, "noise.scale");
  EXPECT_EQ(a.values, (std::vector<std::string>{"0", "0.5", "1"}));
  EXPECT_EQ(test::error_of([] { (void)parse_axis("noise.scale"); }),
            "--axis 'noise.scale': expected key=v1,v2,...");
  EXPECT_EQ(test::error_of([] { (void)parse_axis("noise.scale=1,,2"); }),
            "--axis 'noise.scale=1,,2': empty value");
  EXPECT_EQ(test::error_of([] { (void)parse_axis("=1"); }), "--axis '=1': expected key=v1,v2,...");
}

// Only axes under keys the world never reads let a sweep's cells share one physics run; a
// key that merely begins like one (noiseless) does not count.
TEST(SweepSpec, SharesTheWorldOnlyWhereNoAxisMovesIt) {
  SweepSpec s = tiny();
  EXPECT_TRUE(shares_world(s));
  for (const char* key : {"seed", "noise.axial.a_m", "occlusion.fraction", "occlusion.at",
                          "occluders[0].reflectance", "background.table.height_m",
                          "segmentation.mode", "tracker.mode", "external.timeout_s"}) {
    s.axes = {parse_axis(std::string(key) + "=1,2")};
    EXPECT_TRUE(shares_world(s)) << key;
  }
  for (const char* key : {"chain.friction", "world.dt_s", "camera.fps", "duration_s",
                          "base.waypoints[0].t_s", "actions.pushers[0].radius_m", "noiseless",
                          "seeds", "tracker_x", "scene"}) {
    s.axes = {parse_axis("noise.scale=0,1"), parse_axis(std::string(key) + "=1,2")};
    EXPECT_FALSE(shares_world(s)) << key;
  }
}

TEST(SweepSpec, ValidateNamesTheProblem) {
  SweepSpec s = tiny();
  s.axes.push_back(parse_axis("noise.scale=3"));
  EXPECT_EQ(test::error_of([&] { s.validate(); }), "sweep: axis 'noise.scale' given twice");
  s = tiny();
  s.axes.clear();
  EXPECT_EQ(test::error_of([&] { s.validate(); }), "sweep: no axis (give --axis or --grid)");
  s = tiny();
  s.scene.clear();
  EXPECT_EQ(test::error_of([&] { s.validate(); }), "sweep: no scene (give --scene or an axis 'scene')");
  s = tiny();
  s.axes = {parse_axis("seed=1,2"), parse_axis("mode=paper")};
  EXPECT_EQ(test::error_of([&] { s.validate(); }), "sweep: axis 'mode' clashes with a column name");
  s = tiny();
  s.axes = {parse_axis("a=1,2,3,4,5,6,7,8,9,10"), parse_axis("b=1,2,3,4,5,6,7,8,9,10"),
            parse_axis("c=1,2,3,4,5,6,7,8,9,10"), parse_axis("d=1,2,3,4,5,6,7,8,9,10"),
            parse_axis("e=1,2,3,4,5,6,7,8,9,10"), parse_axis("f=1,2,3,4,5,6,7,8,9,10,11")};
  EXPECT_NE(test::error_of([&] { s.validate(); }).find("at most 1000000"), std::string::npos);
}

TEST(SweepCell, RowMajorOverridesAndSeedsFromTheCellsValues) {
  const SweepSpec s = tiny();
  ASSERT_EQ(s.cells(), 6u);
  const SweepCell c = sweep_cell(s, 3);  // noise.scale index 1, iterations index 1
  EXPECT_EQ(c.values, (std::vector<std::string>{"1", "4"}));
  EXPECT_EQ(c.overrides, (std::vector<std::string>{"noise.scale=1", "tracker.iterations=4"}));
  // The seed depends on the values, not on the index or the rest of the grid: the same
  // values in another grid get the same seed; other values get another.
  SweepSpec other = s;
  other.axes = {parse_axis("noise.scale=1,5"), parse_axis("tracker.iterations=4")};
  EXPECT_EQ(sweep_cell(other, 0).seed, c.seed);
  EXPECT_NE(sweep_cell(s, 2).seed, c.seed);
  EXPECT_NE(sweep_cell(s, 1).seed, sweep_cell(s, 0).seed);
  // A seed axis is the seed.
  SweepSpec seeded = s;
  seeded.axes.push_back(parse_axis("seed=17,18"));
  EXPECT_EQ(sweep_cell(seeded, 1).seed, 18u);
  EXPECT_THROW((void)sweep_cell(s, 6), std::invalid_argument);
}

TEST(SweepGrid, ReadsAxesAndNamesTheLineOfAProblem) {
  const fs::path d = test::scratch_dir("SweepGrid");
  std::ofstream(d / "grid.yaml") << "axes:\n  - noise.scale: [0, 0.5]\n  - seed: [1, 2, 3]\n";
  const auto axes = read_grid(d / "grid.yaml");
  ASSERT_EQ(axes.size(), 2u);
  EXPECT_EQ(axes[1].key, "seed");
  EXPECT_EQ(axes[1].values, (std::vector<std::string>{"1", "2", "3"}));
  std::ofstream(d / "bad.yaml") << "axes:\n  - noise.scale: [0, 0.5]\n  - seed: 3\n";
  EXPECT_EQ(test::error_of([&] { (void)read_grid(d / "bad.yaml"); }),
            (d / "bad.yaml").string() + ":3: seed: expected a non-empty list of values");
  std::ofstream(d / "typo.yaml") << "axis:\n  - seed: [1]\n";
  EXPECT_NE(test::error_of([&] { (void)read_grid(d / "typo.yaml"); }).find("'axes'"), std::string::npos);
  EXPECT_NE(test::error_of([&] { (void)read_grid(d / "none.yaml"); }).find("none.yaml: cannot open grid"),
            std::string::npos);
}

// Cells that replay one cell's physics (what `sweep` does where shares_world) give the
// rows each gives alone, bit for bit but for the wall times: on the default scene (its
// pusher sets off at 0.5 s), with the recording made by a cell other than the first.
TEST_F(Sweep, CellsThatShareTheWorldGiveTheirOwnRows) {
  SweepSpec spec = tiny();
  spec.scene = kScenes / "default.yaml";
  // The pusher's path is the scene's from where it was at 1.016 s, 10 mm from the link, so
  // that it bends the link from frame 3 on: 12 frames a cell rather than 40 (this test runs
  // under the sanitizers in CI).
  spec.set = {"actions.pushers[0].path.waypoints=["
              "{t_s: 0.0, position_m: [0.40, -0.045, 0.5]},"
              "{t_s: 0.984, position_m: [0.40, 0.06, 0.5]},"
              "{t_s: 1.584, position_m: [0.40, -0.12, 0.5]},"
              "{t_s: 1.984, position_m: [0.40, -0.12, 1.2]}]"};
  spec.axes = {parse_axis("noise.scale=0.5,2"), parse_axis("occlusion.fraction=0,0.3")};
  spec.modes = {parse_mode("chain-fit"), parse_mode("paper")};
  spec.frames = 12;
  ASSERT_TRUE(shares_world(spec));
  SweepShared shared;
  const std::vector<std::size_t> order = {3, 0, 1, 2};
  for (const std::size_t c : order) {
    const std::vector<SweepRow> together = run_cell(spec, c, 0, nullptr, &shared);
    ASSERT_NE(shared.physics, nullptr);  // recorded by the first cell run, replayed after
    if (c == order.front()) continue;    // that cell ran its own world
    const std::vector<SweepRow> alone = run_cell(spec, c, 0);
    ASSERT_EQ(together.size(), alone.size());
    for (std::size_t k = 0; k < alone.size(); ++k) EXPECT_EQ(together[k].values, alone[k].values);
  }
  ASSERT_EQ(shared.physics->frames.size(), 12u);
  // The pusher bent the link: the replayed world is not a still one.
  const auto& first = shared.physics->frames[0].nodes_W;
  const auto& last = shared.physics->frames[11].nodes_W;
  double moved = 0;
  for (std::size_t j = 0; j < first.size(); ++j) moved = std::max(moved, (last[j] - first[j]).norm());
  EXPECT_GT(moved, 1e-3) << "the pusher was meant to bend the link by more than 1 mm";
}

// The point of sharding: shards run anywhere, in any order, merge into exactly the table
// one process writes.

TEST_F(Sweep, MergedShardsEqualOneProcessByteForByte) {
  const SweepSpec spec = tiny();
  run_shard(dir / "whole", spec, 0, 1);
  const MergeResult whole = merge_sweep(dir / "whole");
  EXPECT_EQ(whole.cells, 6u);
  EXPECT_EQ(whole.rows, 12u);
  for (const int i : {2, 0, 1}) run_shard(dir / "sharded", spec, i, 3);
  const MergeResult merged = merge_sweep(dir / "sharded");
  EXPECT_EQ(merged.shard_files, 3u);
  const std::string cells = slurp(dir / "whole" / "cells.csv");
  EXPECT_EQ(cells, slurp(dir / "sharded" / "cells.csv"));
  // The table is the grid: header, then cell 0 paper, cell 0 paper-centred, ...
  std::istringstream lines(cells);
  std::string line;
  std::getline(lines, line);
  EXPECT_EQ(line.rfind("cell,mode,noise.scale,tracker.iterations,cell_seed,frames,", 0), 0u);
  std::getline(lines, line);
  EXPECT_EQ(line.rfind("0,paper,0,2,", 0), 0u) << line;
  std::getline(lines, line);
  EXPECT_EQ(line.rfind("0,paper-centred,0,2,", 0), 0u) << line;
  EXPECT_EQ(cells.find("time_ms"), std::string::npos) << "timing belongs in cells_timing.csv";
  const std::string timing = slurp(dir / "sharded" / "cells_timing.csv");
  EXPECT_EQ(timing.rfind("cell,mode,time_ms_mean,", 0), 0u);
  EXPECT_EQ(std::count(timing.begin(), timing.end(), '\n'), 13);
}

// The CLI writes a shard from its cells' records (so that its memory does not grow with
// cells): the same bytes as from the rows in memory; a failed cell is left out; a missing
// record of a cell that did not fail is named, and no shard file is left.
TEST_F(Sweep, ShardFromCellRecordsEqualsShardFromRows) {
  const SweepSpec spec = tiny();
  write_manifest(dir / "rows", spec);
  write_manifest(dir / "records", spec);
  std::vector<SweepRow> rows, without_3;
  for (const std::size_t c : shard_cells(spec, 1, 2)) {
    const std::vector<SweepRow> cell = run_cell(spec, c, 0);
    for (const SweepRow& r : cell) {
      rows.push_back(r);
      if (c != 3) without_3.push_back(r);
    }
    write_cell_record(dir / "records", spec, 1, 2, c, cell);
  }
  write_shard(dir / "rows", spec, 1, 2, rows);
  write_shard_from_records(dir / "records", spec, 1, 2);
  const std::string name = shard_file_name(1, 2);
  EXPECT_EQ(slurp(dir / "records" / name), slurp(dir / "rows" / name));
  // Cell 3 failed: its record is not read (here it is gone) and the rows leave it out.
  fs::remove(cell_records_dir(dir / "records", 1, 2) / "3.csv");
  write_shard(dir / "rows", spec, 1, 2, without_3, {{3, "it hung"}});
  write_shard_from_records(dir / "records", spec, 1, 2, {{3, "it hung"}});
  EXPECT_EQ(slurp(dir / "records" / name), slurp(dir / "rows" / name));
  fs::remove(dir / "records" / name);
  const std::string e =
      test::error_of([&] { write_shard_from_records(dir / "records", spec, 1, 2); });
  EXPECT_NE(e.find("3.csv: cell 3's record is missing or torn"), std::string::npos) << e;
  EXPECT_FALSE(fs::exists(dir / "records" / name));
}

// The manifest's integers are checked before they are converted (fuzz_shard: a version
// of 2e35 was undefined behaviour in the conversion to int).
TEST_F(Sweep, AManifestIntegerOutOfRangeIsNamed) {
  write_manifest(dir, tiny());
  const std::string text = slurp(dir / "sweep.json");
  for (const std::string bad : {"2.2e+35", "-1", "1.5", "\"1\"", "18446744073709551615"}) {
    std::string edited = text;
    const std::size_t at = edited.find("\"frames\": 2");
    ASSERT_NE(at, std::string::npos) << text;
    edited.replace(at, 11, "\"frames\": " + bad);
    std::ofstream(dir / "sweep.json") << edited;
    const std::string e = test::error_of([&] { (void)read_manifest(dir); });
    EXPECT_NE(e.find("sweep.json: frames " + bad + ": expected an integer in [0, 2147483647]"),
              std::string::npos)
        << e;
  }
}

TEST_F(Sweep, MergeNamesMissingAndDoubledCells) {
  const SweepSpec spec = tiny();
  run_shard(dir, spec, 0, 3);  // cells 0, 3
  run_shard(dir, spec, 1, 3);  // cells 1, 4
  std::string e = test::error_of([&] { (void)merge_sweep(dir); });
  EXPECT_NE(e.find("2 of 6 cells missing (2, 5)"), std::string::npos) << e;
  EXPECT_FALSE(fs::exists(dir / "cells.csv"));
  run_shard(dir, spec, 2, 3);
  run_shard(dir, spec, 0, 2);  // cells 0, 2, 4 again
  e = test::error_of([&] { (void)merge_sweep(dir); });
  EXPECT_NE(e.find("3 cells doubled (0, 2, 4)"), std::string::npos) << e;
  EXPECT_FALSE(fs::exists(dir / "cells.csv"));
  fs::remove(dir / shard_file_name(0, 2));
  EXPECT_NO_THROW((void)merge_sweep(dir));
  EXPECT_NE(test::error_of([&] { (void)merge_sweep(dir / "nothing"); }).find("no sweep manifest"),
            std::string::npos);
}

// Shard files copied in again and again are refused once they hold more rows than the
// grid twice over, before all are held; a few doubled shards are named by their cells.
TEST_F(Sweep, MergeRefusesShardsCopiedWithoutEnd) {
  const SweepSpec spec = tiny();  // 6 cells x 2 modes: 12 rows
  run_shard(dir, spec, 0, 1);
  for (int k = 0; k < 8; ++k)
    fs::copy_file(dir / shard_file_name(0, 1), dir / shard_file_name(k, 99));
  const std::string e = test::error_of([&] { (void)merge_sweep(dir); });
  EXPECT_NE(e.find("hold 96 rows, where the grid has 12 (shards copied in more than once?)"),
            std::string::npos)
      << e;
  EXPECT_FALSE(fs::exists(dir / "cells.csv"));
}

TEST_F(Sweep, CompleteShardsAreRecognizedAndOthersAreNot) {
  const SweepSpec spec = tiny();
  EXPECT_FALSE(shard_complete(dir, spec, 0, 2));
  run_shard(dir, spec, 0, 2);
  EXPECT_TRUE(shard_complete(dir, spec, 0, 2));
  EXPECT_FALSE(shard_complete(dir, spec, 1, 2));
  // A torn or foreign file is not complete: the re-run redoes it.
  const fs::path f = dir / shard_file_name(0, 2);
  const std::string text = slurp(f);
  std::ofstream(f) << text.substr(0, text.size() / 2);
  EXPECT_FALSE(shard_complete(dir, spec, 0, 2));
  // Another grid in the same directory is refused, naming what differs.
  SweepSpec other = spec;
  other.frames = 3;
  const std::string e = test::error_of([&] { write_manifest(dir, other); });
  EXPECT_NE(e.find("describes another sweep: frames is 2, this run has 3"), std::string::npos) << e;
}

// The digest covers the scene file's bytes: a sweep resumed after its scene changed would
// mix two scenes, and is refused by name; the digest moves with every setting.
TEST_F(Sweep, TheDigestCoversSettingsAndSceneBytes) {
  const fs::path scene = dir / "scene.yaml";
  std::ofstream(scene) << slurp(kScenes / "static.yaml");
  SweepSpec spec = tiny();
  spec.scene = scene;
  const std::string d = sweep_digest(spec);
  EXPECT_EQ(d.size(), 16u);
  EXPECT_EQ(sweep_digest(spec), d);
  write_manifest(dir / "sweep", spec);
  EXPECT_NO_THROW(write_manifest(dir / "sweep", spec));
  std::ofstream(scene, std::ios::app) << "# edited\n";
  EXPECT_NE(sweep_digest(spec), d);
  const std::string e = test::error_of([&] { write_manifest(dir / "sweep", spec); });
  EXPECT_NE(e.find("describes another sweep: digest " + d + ", this run has " + sweep_digest(spec) +
                   " (a scene file changed since the sweep began"),
            std::string::npos)
      << e;
  SweepSpec other = spec;
  other.frames = 3;
  EXPECT_NE(sweep_digest(other), sweep_digest(spec));
  other = spec;
  other.set = {"noise.scale=2"};
  EXPECT_NE(sweep_digest(other), sweep_digest(spec));
}

// Issue 19, F3: a shard file from another sweep with the same columns (other seeds, another
// --frames, another mode) copied into this sweep's directory is refused by merge, naming
// the file, line and field, and is not "complete" to a re-run (which then redoes it).
TEST_F(Sweep, MergeRefusesAShardOfAnotherSweep) {
  SweepSpec spec = tiny();
  spec.axes = {parse_axis("seed=1,2")};
  const auto foreign = [&](const SweepSpec& other, int line, const std::string& says) {
    const fs::path mine = dir / "mine", theirs = dir / "theirs";
    fs::remove_all(mine);
    fs::remove_all(theirs);
    run_shard(mine, spec, 0, 2);
    run_shard(theirs, other, 1, 2);
    fs::copy_file(theirs / shard_file_name(1, 2), mine / shard_file_name(1, 2));
    const std::string e = test::error_of([&] { (void)merge_sweep(mine); });
    EXPECT_NE(e.find((mine / shard_file_name(1, 2)).string() + ":" + std::to_string(line) + ": " +
                     says),
              std::string::npos)
        << e;
    EXPECT_FALSE(fs::exists(mine / "cells.csv")) << says;
    EXPECT_FALSE(shard_complete(mine, spec, 1, 2)) << says;
  };
  SweepSpec seeds = spec;
  seeds.axes = {parse_axis("seed=5,6")};
  foreign(seeds, 2, "cell 1's seed is '6', this sweep's grid has '2' (a shard of another sweep?)");
  SweepSpec frames = spec;
  frames.frames = 3;
  foreign(frames, 2, "cell 1 ran 3 frames, this sweep runs 2 (a shard of another sweep?)");
  SweepSpec modes = spec;
  modes.modes = {parse_mode("paper"), parse_mode("accelerated-som")};
  foreign(modes, 2,
          "its sweep digest is '" + sweep_digest(modes) + "', this sweep's is '" +
              sweep_digest(spec) + "' (a shard of another sweep");
  // Issue 59: the same axes, frames and modes, but another --set or another scene: every
  // row's values match the grid, and only the digest tells.
  SweepSpec set = spec;
  set.set = {"noise.scale=2"};
  foreign(set, 2, "its sweep digest is '" + sweep_digest(set) + "'");
  const fs::path copy = dir / "static_copy.yaml";
  std::ofstream(copy) << slurp(kScenes / "static.yaml") << "\n# the same scene, edited\n";
  SweepSpec scene = spec;
  scene.scene = copy;
  foreign(scene, 2, "its sweep digest is '" + sweep_digest(scene) + "'");
  // A row of this sweep's own shard, edited to name a tracker it does not compare: the
  // digest matches, the tracker check names it.
  run_shard(dir / "mine", spec, 1, 2);
  const fs::path own = dir / "mine" / shard_file_name(1, 2);
  const std::string good = slurp(own);
  std::string edited = good;
  edited.replace(edited.find(",paper,"), 7, ",accelerated-som,");
  std::ofstream(own) << edited;
  EXPECT_NE(test::error_of([&] {
              (void)merge_sweep(dir / "mine");
            }).find(own.string() + ":2: tracker 'accelerated-som' is not one this sweep compares"),
            std::string::npos);
  // A shard whose cells all failed has rows only in its .failed.csv: they carry the
  // digest too, so another sweep's failures are refused as well.
  std::ofstream(own) << good.substr(0, good.find('\n') + 1);
  std::ofstream(dir / "mine" / "shard_1_of_2.failed.csv")
      << "cell,error,sweep_digest\n1,boom,0123456789abcdef\n";
  EXPECT_NE(test::error_of([&] { (void)merge_sweep(dir / "mine"); })
                .find("shard_1_of_2.failed.csv:2: its sweep digest is '0123456789abcdef', this "
                      "sweep's is '" +
                      sweep_digest(spec) + "' (a shard of another sweep)"),
            std::string::npos);
  fs::remove(dir / "mine" / "shard_1_of_2.failed.csv");
  // The sweep's own shard merges.
  run_shard(dir / "mine", spec, 1, 2);
  EXPECT_TRUE(shard_complete(dir / "mine", spec, 1, 2));
  EXPECT_NO_THROW((void)merge_sweep(dir / "mine"));
}

TEST_F(Sweep, BadSceneKeysInACellAreNamed) {
  SweepSpec spec = tiny();
  spec.axes = {parse_axis("noise.scael=1,2")};
  const std::string e = test::error_of([&] { (void)run_cell(spec, 0, 0); });
  EXPECT_NE(e.find("--axis noise.scael=1: noise.scael: unknown key"), std::string::npos) << e;
  // Each override is named by where it came from, the last of a key's (which set it).
  spec.axes = {parse_axis("noise.scale=1,-2")};
  spec.set = {"noise.scale=-2", "seed=-1"};
  std::string set = test::error_of([&] { (void)run_cell(spec, 0, 0); });
  EXPECT_NE(set.find(": --set seed=-1: "), std::string::npos) << set;
  spec.set = {"noise.scale=-2"};
  set = test::error_of([&] { (void)run_cell(spec, 1, 0); });
  EXPECT_NE(set.find(": --axis noise.scale=-2: "), std::string::npos) << set;
}

}  // namespace
}  // namespace linksight::sim
