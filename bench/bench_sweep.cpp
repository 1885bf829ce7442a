// Sweep throughput (issue 7): cells/s of the robustness grid's cells on this machine, one
// process, each cell's sensor on every core (as `linksight sweep` without --shard). The
// arguments are the cells per iteration and the camera frames per cell (91: the whole
// 3 s robustness episode). Three modes per cell, as the robustness suites compare.
#include <benchmark/benchmark.h>

#include "linksight/sim/sweep.hpp"

namespace {
using namespace linksight;
using namespace linksight::sim;

void BM_SweepCells(benchmark::State& state) {
  SweepSpec spec;
  spec.scene = std::string(LINKSIGHT_SCENE_DIR) + "/robustness_static.yaml";
  spec.axes = {{"noise.scale", {"0", "1", "4"}}, {"occlusion.fraction", {"0", "0.3"}}};
  spec.modes = {parse_mode("paper"), parse_mode("paper-centred"), parse_mode("accelerated-som")};
  spec.frames = static_cast<int>(state.range(1));
  const auto cells = static_cast<std::size_t>(state.range(0));
  std::int64_t done = 0;
  for (auto _ : state) {
    for (std::size_t i = 0; i < cells; ++i) {
      const std::vector<SweepRow> rows = run_cell(spec, i % spec.cells(), 0);
      benchmark::DoNotOptimize(rows.data());
      ++done;
    }
  }
  const double n = static_cast<double>(done);
  state.counters["cells_per_s"] = benchmark::Counter(n, benchmark::Counter::kIsRate);
  state.counters["frames_per_s"] =
      benchmark::Counter(n * static_cast<double>(spec.frames), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_SweepCells)->Args({6, 91})->Args({6, 2})->Unit(benchmark::kSecond)->UseRealTime();

}  // namespace
