// Physics cost of the 11-component chain: ms per 1 kHz step while a force bends it.
// (A pusher body in contact arrives with the pusher work; see bench/README.md.)
#include <benchmark/benchmark.h>

#include "linksight/sim/world.hpp"

namespace {
using namespace linksight::sim;

void BM_WorldStep(benchmark::State& state) {
  Eigen::Isometry3d X_WB = Eigen::Isometry3d::Identity();
  X_WB.translation() = Eigen::Vector3d(0, 0, 0.5);
  World w(ChainParams{}, WorldParams{}, X_WB);
  // A slipping load keeps the solver busy: every joint motor active.
  ForceAction load;
  load.component = 10;
  load.force_W = Eigen::Vector3d(0, 8.0, 0);
  load.t_end = 1e9;
  w.add_force(load);
  for (auto _ : state) w.step();
  state.counters["sim_s_per_s"] = benchmark::Counter(static_cast<double>(state.iterations()) * 1e-3,
                                                     benchmark::Counter::kIsRate);
}
BENCHMARK(BM_WorldStep)->Unit(benchmark::kMillisecond);

}  // namespace
