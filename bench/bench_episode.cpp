// End to end on scenes/default.yaml: physics, render, extraction, the paper tracker and
// the scoring, frame after frame as `linksight run` does (without file output). Reports
// frames/s (the issue 6 target: >= 100 on 2 cores) and the ms of each stage. The argument
// is the number of frames per iteration (one episode from t = 0); `chain_only` renders as
// `linksight run` does (the chain's box; see RenderExtent), `whole` every pixel; the
// `_one_field` cases with the camera before issue 20 (sr300-one-field) instead of the
// scene's two-scale sr300, side by side.
#include <benchmark/benchmark.h>

#include "linksight/sim/episode.hpp"

namespace {
using namespace linksight::sim;

void BM_Episode(benchmark::State& state, bool chain_only, bool one_field = false) {
  Scene scene = load_scene(std::string(LINKSIGHT_SCENE_DIR) + "/default.yaml");
  if (one_field) scene.noise = NoiseParams::sr300_one_field();
  EpisodeOptions o;
  o.frames = static_cast<int>(state.range(0));
  o.chain_only_images = chain_only;
  double physics = 0, render = 0, extract = 0, track = 0, score = 0;
  std::int64_t frames = 0;
  for (auto _ : state) {
    Episode e(scene, o);
    while (e.done() < e.frames()) {
      const EpisodeFrame& f = e.step();
      benchmark::DoNotOptimize(f.scores.data());
      const EpisodeTimes& t = e.last_times();
      physics += t.physics;
      render += t.render;
      extract += t.extract;
      score += t.score;
      track += f.results[0].time_s;
      ++frames;
    }
  }
  const double n = static_cast<double>(frames);
  state.counters["frames_per_s"] = benchmark::Counter(n, benchmark::Counter::kIsRate);
  state.counters["physics_ms"] = 1e3 * physics / n;
  state.counters["render_ms"] = 1e3 * render / n;
  state.counters["extract_ms"] = 1e3 * extract / n;
  state.counters["track_ms"] = 1e3 * track / n;
  state.counters["score_ms"] = 1e3 * score / n;
}
BENCHMARK_CAPTURE(BM_Episode, chain_only, true)->Arg(241)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Episode, whole, false)->Arg(241)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Episode, chain_only_one_field, true, true)
    ->Arg(241)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(BM_Episode, whole_one_field, false, true)
    ->Arg(241)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
