// The external-tracker protocol's own cost per frame (issue 18): linksight sends N points
// to bench/null_tracker.py, which reads them and answers at once, and reads the answer.
// Beside it, in the same run, a built-in paper-mode step on the same cloud, for scale.
//   linksight_bench_protocol                 # 5k, 20k, 100k points
#include <benchmark/benchmark.h>

#include <string>

#include "bench_cloud.hpp"
#include "linksight/sim/external_tracker.hpp"
#include "linksight/tracker/tracker.hpp"

namespace {
using namespace linksight;

void BM_Protocol(benchmark::State& state) {
  const Cloud cloud = bench::make_cloud(static_cast<std::size_t>(state.range(0)));
  sim::ExternalTracker t({"null", std::string(LINKSIGHT_PYTHON3) + " " + LINKSIGHT_BENCH_DIR +
                                      "/null_tracker.py"},
                         sim::ExternalParams{}, 12, io::Intrinsics{}, ComponentGeometry{},
                         BasePriorParams{});
  int frame = 0;
  (void)t.step({frame++, 0.0, &cloud, nullptr});  // the interpreter's start is not the steady state
  for (auto _ : state) {
    FrameResult r = t.step({frame++, 0.0, &cloud, nullptr});
    benchmark::DoNotOptimize(r.nodes.data());
  }
  state.counters["points"] = static_cast<double>(cloud.size());
}
// For scale, in the same run: a built-in paper-mode frame on the same cloud.
void BM_PaperStep(benchmark::State& state) {
  const Cloud cloud = bench::make_cloud(static_cast<std::size_t>(state.range(0)));
  TrackerParams p;
  p.mode = parse_mode("paper");
  p.nodes = 12;
  p.iterations = 4;
  p.compute_sdf = false;
  Tracker tracker(p);
  (void)tracker.step(cloud);
  for (auto _ : state) {
    FrameResult r = tracker.step(cloud);
    benchmark::DoNotOptimize(r.nodes.data());
  }
}
BENCHMARK(BM_PaperStep)->Arg(5000)->Arg(20000)->Arg(100000)->Unit(benchmark::kMillisecond)->UseRealTime();

BENCHMARK(BM_Protocol)->Arg(5000)->Arg(20000)->Arg(100000)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
