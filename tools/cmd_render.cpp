// linksight render: a scene's physics seen by the simulated SR300, recorded like a real
// recording (see sim/recording.hpp for the layout).
#include <iostream>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <memory>

#include "commands.hpp"
#include "linksight/sim/extract.hpp"
#include "linksight/sim/recording.hpp"
#include "linksight/sim/scene.hpp"

namespace linksight::cli {
namespace {

struct RenderOptions {
  std::string scene;
  int frames = 0;      // 0: the scene's duration
  std::string noise;   // empty: the scene's noise block
  int threads = 0;
  std::string out = "out/render";
  bool force = false;
  bool quiet = false;
};

int run_render(const RenderOptions& o) {
  sim::Scene scene = sim::load_scene(o.scene);
  if (!o.noise.empty()) scene.noise = sim::NoiseParams::preset(o.noise);
  if (o.frames < 0)
    throw std::invalid_argument("--frames = " + std::to_string(o.frames) + ": must be >= 0");
  if (o.threads < 0)
    throw std::invalid_argument("--threads = " + std::to_string(o.threads) + ": must be >= 0");
  const int frames = sim::camera_frames(scene, o.frames);
  std::unique_ptr<sim::World> world = sim::make_world(scene);
  std::unique_ptr<sim::Sensor> sensor = sim::make_sensor(scene, o.threads);
  sim::Recorder recorder(o.out, scene.camera, scene.chain.geometry, o.force);
  sim::DepthFrame image;
  std::size_t points = 0;
  double occluded = 0;
  for (int f = 0; f < frames; ++f) {
    world->step_until(f / scene.camera.fps);
    const sim::Truth truth = world->truth();
    sensor->render(truth.X_WK, truth.t, scene.seed, static_cast<std::uint64_t>(f), image);
    const Cloud cloud = sim::extract_cloud(image, scene.camera.intrinsics,
                                           scene.chain.geometry.count, scene.segmentation,
                                           scene.seed, static_cast<std::uint64_t>(f));
    points += cloud.size();
    occluded = std::max(occluded, image.link_occluded_fraction);
    recorder.write_frame(f, truth, image, cloud);
    if (!o.quiet && isatty(fileno(stderr))) std::cerr << "\rrender: frame " << f + 1 << "/" << frames << std::flush;
  }
  recorder.commit();
  if (!o.quiet) {
    if (isatty(fileno(stderr))) std::cerr << "\n";
    std::cout << "rendered " << frames << " frames of " << o.scene << " ("
              << points / std::max(frames, 1) << " points per frame, up to "
              << static_cast<int>(occluded * 100 + 0.5) << "% of the link occluded); wrote "
              << o.out << "\n  track the segmented clouds: linksight track --input " << o.out
              << "/clouds\n  or the raw depth, as from a camera: linksight track --input " << o.out
              << "/depth --max-depth M --crop ...\n";
  }
  return kExitOk;
}

}  // namespace

Runner add_render(CLI::App& app) {
  auto o = std::make_shared<RenderOptions>();
  app.add_option("--scene", o->scene, "scene file (YAML), e.g. scenes/occluder_pass.yaml")
      ->required();
  app.add_option("--frames", o->frames, "frames to render (0: the scene's duration)")
      ->capture_default_str();
  app.add_option("--noise", o->noise,
                 "noise preset replacing the scene's: off | sr300 | sr300-one-field")
      ->check(CLI::IsMember(sim::NoiseParams::preset_names()));
  app.add_option("--threads", o->threads, "OpenMP threads for ray casting (0: default)")
      ->capture_default_str();
  app.add_option("--out", o->out,
                 "output directory: depth/, labels/, clouds/, intrinsics.json, camera.json, "
                 "truth.csv (camera frame), occlusion.csv, chain.json (component geometry), base_pose.csv (true X_CB, for track "
                 "--base-prior)")
      ->capture_default_str();
  app.add_flag("--force", o->force, "replace an existing output directory");
  app.add_flag("--quiet", o->quiet, "print nothing on success");
  return [o] { return run_render(*o); };
}

}  // namespace linksight::cli
