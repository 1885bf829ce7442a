// Physics cost of the 11-component chain at 1 kHz: ms per step (and simulated seconds per
// wall second) with a pusher in contact, pressing sideways into the chain and bending it.
#include <benchmark/benchmark.h>

#include "linksight/sim/world.hpp"

namespace {
using namespace linksight::sim;

void BM_WorldStepPusherInContact(benchmark::State& state) {
  Eigen::Isometry3d X_WB = Eigen::Isometry3d::Identity();
  X_WB.translation() = Eigen::Vector3d(0, 0, 0.5);
  World w(ChainParams{}, WorldParams{}, X_WB);
  // A sphere that starts touching the outer half of the chain and keeps pushing slowly
  // (5 cm/s), so nearly every timed step has contact and slipping joints.
  PusherParams pusher;
  pusher.radius = 0.02;
  Eigen::Isometry3d A = Eigen::Isometry3d::Identity(), B = Eigen::Isometry3d::Identity();
  A.translation() = Eigen::Vector3d(0.40, -0.034, 0.5);
  B.translation() = Eigen::Vector3d(0.40, 4.966, 0.5);
  pusher.path = BaseTrajectory({{0.0, A}, {100.0, B}});
  w.add_pusher(pusher);
  for (int i = 0; i < 200; ++i) w.step();  // into contact
  std::int64_t contact_steps = 0;
  for (auto _ : state) {
    w.step();
    state.PauseTiming();
    contact_steps += w.truth().contact;
    state.ResumeTiming();
  }
  state.counters["contact_fraction"] =
      static_cast<double>(contact_steps) / static_cast<double>(state.iterations());
  state.counters["sim_s_per_s"] = benchmark::Counter(static_cast<double>(state.iterations()) * 1e-3,
                                                     benchmark::Counter::kIsRate);
}
BENCHMARK(BM_WorldStepPusherInContact)->Unit(benchmark::kMillisecond);

}  // namespace
