// One simulated SR300 frame (640x480) with sr300-one-field noise (the two-scale sr300 in
// the *_two_scale cases): render (scene update, primary and
// projector-shadow rays, occlusion pass, noise and artefacts) plus cloud extraction, for
// the link alone and for scenes/occluder_pass.yaml at t = 2.3 s (the hand in front of the
// link's middle; table, wall and mug behind).
// Counters give the ms of each stage; the argument is the OpenMP thread count.
#include <benchmark/benchmark.h>

#include <chrono>

#include "linksight/sim/extract.hpp"
#include "linksight/sim/scene.hpp"

namespace {
using namespace linksight::sim;

// The noise: the one-field `sr300-one-field` preset (the camera before issue 20, the
// baseline of the ratios in bench/README.md), two anisotropic fields or one Matern-5/2
// field of ranges 7 x 8 px on top of it, or the two-scale `sr300` preset that
// calibrate-noise fits to the shared SR305 frames (issue 20; docs/sensor.md): what each
// costs.
enum class Field { one_field, two_terms, matern, two_scale };

void BM_SensorFrame(benchmark::State& state, const char* scene_file, ExtractParams::Mode mode,
                    bool chain_only = false, Field field = Field::one_field) {
  Scene scene = load_scene(std::string(LINKSIGHT_SCENE_DIR) + "/" + scene_file);
  scene.segmentation.mode = mode;
  // (the scenes name the preset and nothing else of the noise)
  scene.noise = field == Field::two_scale ? NoiseParams::sr300() : NoiseParams::sr300_one_field();
  if (field == Field::two_terms) {
    scene.noise.axial.correlation_cols_px = 2.5;
    scene.noise.axial.low_share = 0.5;
    scene.noise.axial.low_rows_px = 6;
    scene.noise.axial.low_cols_px = 8;
  } else if (field == Field::matern) {
    scene.noise.axial.kernel = AxialKernel::matern52;
    scene.noise.axial.correlation_px = 7;
    scene.noise.axial.correlation_cols_px = 8;
  }
  auto world = make_world(scene);
  const double t = 2.3;
  const Truth truth = world->truth();  // the chain at rest; the hand moves with t
  auto sensor = make_sensor(scene, static_cast<int>(state.range(0)));
  DepthFrame frame;
  RenderExtent extent;
  extent.chain_only = chain_only;
  double cast = 0, occlusion = 0, noise = 0, scene_s = 0, extract = 0;
  std::uint64_t f = 0;
  std::size_t points = 0;
  for (auto _ : state) {
    sensor->render(truth.X_WK, t, scene.seed, f, frame, extent);
    const auto t0 = std::chrono::steady_clock::now();
    const linksight::Cloud cloud = extract_cloud(frame, scene.camera.intrinsics,
                                                 scene.chain.geometry.count, scene.segmentation,
                                                 scene.seed, f);
    extract += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    benchmark::DoNotOptimize(cloud.xyz.data());
    points = cloud.size();
    const SensorTimes& s = sensor->last_times();
    scene_s += s.scene;
    cast += s.cast;
    occlusion += s.occlusion;
    noise += s.noise;
    ++f;
  }
  const double n = static_cast<double>(state.iterations());
  state.counters["scene_ms"] = 1e3 * scene_s / n;
  state.counters["cast_shadow_ms"] = 1e3 * cast / n;
  state.counters["occlusion_ms"] = 1e3 * occlusion / n;
  state.counters["noise_ms"] = 1e3 * noise / n;
  state.counters["extract_ms"] = 1e3 * extract / n;
  state.counters["points"] = static_cast<double>(points);
  state.counters["occluded_pct"] = 100.0 * frame.link_occluded_fraction;
}
// The link alone (scenes/static.yaml): most rays miss, as with a far background.
BENCHMARK_CAPTURE(BM_SensorFrame, link_only, "static.yaml", ExtractParams::Mode::truth)
    ->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
// Every ray hits: table, wall, mug, hand and board.
BENCHMARK_CAPTURE(BM_SensorFrame, occluder_pass_truth, "occluder_pass.yaml",
                  ExtractParams::Mode::truth)
    ->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
// The README demo's scene (pusher in contact, table and wall behind): what
// linksight_bench_episode renders every frame.
BENCHMARK_CAPTURE(BM_SensorFrame, default_truth, "default.yaml", ExtractParams::Mode::truth)
    ->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
// The same, rendering only the chain's box, as `linksight run` does.
BENCHMARK_CAPTURE(BM_SensorFrame, default_chain_only, "default.yaml", ExtractParams::Mode::truth,
                  true)
    ->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
// Both again with the two-term axial field: widths 6 and 8 px, so its blur reaches 24 px.
BENCHMARK_CAPTURE(BM_SensorFrame, default_truth_two_terms, "default.yaml",
                  ExtractParams::Mode::truth, false, Field::two_terms)
    ->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_SensorFrame, default_chain_only_two_terms, "default.yaml",
                  ExtractParams::Mode::truth, true, Field::two_terms)
    ->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
// And with one Matern field of ranges 7 x 8 px: its filter reaches 21 x 24 px.
BENCHMARK_CAPTURE(BM_SensorFrame, default_truth_matern, "default.yaml",
                  ExtractParams::Mode::truth, false, Field::matern)
    ->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_SensorFrame, default_chain_only_matern, "default.yaml",
                  ExtractParams::Mode::truth, true, Field::matern)
    ->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
// And with the two-scale structure: the low field (6 px on a 2 px grid) reaches 18 px, and
// each pixel scales its two fields apart.
BENCHMARK_CAPTURE(BM_SensorFrame, default_truth_two_scale, "default.yaml",
                  ExtractParams::Mode::truth, false, Field::two_scale)
    ->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_SensorFrame, default_chain_only_two_scale, "default.yaml",
                  ExtractParams::Mode::truth, true, Field::two_scale)
    ->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_SensorFrame, occluder_pass_depth, "occluder_pass.yaml",
                  ExtractParams::Mode::depth)
    ->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
