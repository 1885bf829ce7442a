// Tracker throughput: paper mode, 12 nodes, 4 iterations, ms per frame over N points,
// for every back end; chain-fit beside it on every back end (tracker_step_chain_fit/;
// on OpenCL its passes run as kernels when the device has double precision),
// for the ratio mode / paper mode measured in one run; chain-fit's first frame (its fresh
// start) on the CPU back ends (tracker_first_frame_chain_fit/). `--smoke` registers one tiny
// size only (ctest runs it untimed).
//   linksight_bench --benchmark_filter=opencl     # one back end (the engine is in the name)
#include <benchmark/benchmark.h>

#include <cstring>
#include <string>
#include <vector>

#include "bench_cloud.hpp"
#include "linksight/tracker/tracker.hpp"

namespace {
using namespace linksight;

// The tracker every bench here runs: 12 nodes, 4 iterations (paper mode's), no SDF.
TrackerParams bench_params(const char* mode, BackendKind backend,
                           ClAccumulation accumulation = ClAccumulation::reduction) {
  TrackerParams p;
  p.mode = parse_mode(mode);
  p.backend = backend;
  p.opencl.accumulation = accumulation;
  p.nodes = 12;
  p.iterations = 4;
  p.compute_sdf = false;  // the metric is evaluation, not tracking
  return p;
}

// End-to-end ms/frame (for OpenCL: upload + kernels + read-backs) and, for OpenCL, the
// kernels' own device time per frame from profiling events ("kernel_ms").
void BM_TrackerStep(benchmark::State& state, BackendKind backend, ClAccumulation accumulation,
                    const char* mode) {
  const Cloud cloud = bench::make_cloud(static_cast<std::size_t>(state.range(0)));
  Tracker tracker(bench_params(mode, backend, accumulation));
  (void)tracker.step(cloud);  // initialization (and kernel build) is not the steady state
  std::int64_t reinits = 0;
  double device_s = 0.0;
  for (auto _ : state) {
    FrameResult r = tracker.step(cloud);
    reinits += r.reinit;
    device_s += r.device_time_s;
    benchmark::DoNotOptimize(r.nodes.data());
  }
  state.counters["points"] = static_cast<double>(cloud.size());
  state.counters["reinit"] = static_cast<double>(reinits);  // 0 in the steady state
  if (backend == BackendKind::opencl) {
    state.counters["kernel_ms"] = 1e3 * device_s / static_cast<double>(state.iterations());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(cloud.size()));
}

// chain-fit's fresh start, ms: a new tracker's first frame (initialization, the slide, the
// fits from each start and of the best moved by one component either way). Paid on the
// first frame, a restart and a re-initialization; the steady state above never pays it.
void BM_TrackerFirstFrame(benchmark::State& state, BackendKind backend) {
  const Cloud cloud = bench::make_cloud(static_cast<std::size_t>(state.range(0)));
  const TrackerParams p = bench_params("chain-fit", backend);
  for (auto _ : state) {
    Tracker tracker(p);
    FrameResult r = tracker.step(cloud);
    benchmark::DoNotOptimize(r.nodes.data());
  }
  state.counters["points"] = static_cast<double>(cloud.size());
}

}  // namespace

int main(int argc, char** argv) {
  bool smoke = false;
  std::vector<char*> args;
  for (int i = 0; i < argc; ++i) {
    if (std::strcmp(argv[i], "--smoke") == 0) {
      smoke = true;
    } else {
      args.push_back(argv[i]);
    }
  }
  const std::vector<std::int64_t> sizes =
      smoke ? std::vector<std::int64_t>{300}
            : std::vector<std::int64_t>{5000, 20000, 100000, 300000};
  const auto at_sizes = [&sizes](benchmark::internal::Benchmark* bm) {
    for (auto n : sizes) bm->Arg(n);
    bm->Unit(benchmark::kMillisecond)->UseRealTime();
  };
  struct Engine {
    const char* name;
    BackendKind kind;
    ClAccumulation accumulation;
  };
  for (const Engine& e :
       {Engine{"serial", BackendKind::serial, ClAccumulation::reduction},
        Engine{"openmp", BackendKind::openmp, ClAccumulation::reduction},
        Engine{"opencl_reduction", BackendKind::opencl, ClAccumulation::reduction},
        Engine{"opencl_atomic", BackendKind::opencl, ClAccumulation::atomic}}) {
    auto* bm = benchmark::RegisterBenchmark((std::string("tracker_step/") + e.name).c_str(),
                                            BM_TrackerStep, e.kind, e.accumulation, "paper");
    at_sizes(bm);
  }
  for (const Engine& e : {Engine{"serial", BackendKind::serial, ClAccumulation::reduction},
                          Engine{"openmp", BackendKind::openmp, ClAccumulation::reduction},
                          Engine{"opencl", BackendKind::opencl, ClAccumulation::reduction}}) {
    auto* bm = benchmark::RegisterBenchmark(
        (std::string("tracker_step_chain_fit/") + e.name).c_str(), BM_TrackerStep, e.kind,
        e.accumulation, "chain-fit");
    at_sizes(bm);
  }
  for (const Engine& e : {Engine{"serial", BackendKind::serial, ClAccumulation::reduction},
                          Engine{"openmp", BackendKind::openmp, ClAccumulation::reduction}}) {
    auto* bm = benchmark::RegisterBenchmark(
        (std::string("tracker_first_frame_chain_fit/") + e.name).c_str(), BM_TrackerFirstFrame,
        e.kind);
    at_sizes(bm);
  }
  int n = static_cast<int>(args.size());
  benchmark::Initialize(&n, args.data());
  if (benchmark::ReportUnrecognizedArguments(n, args.data())) return 2;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
