// linksight simulate: a scene's physics, truth sampled at the camera rate.
#include <filesystem>
#include <iostream>
#include <memory>
#include <sstream>

#include "commands.hpp"
#include "linksight/io/atomic_file.hpp"
#include "linksight/io/error.hpp"
#include "linksight/sim/recording.hpp"
#include "linksight/sim/scene.hpp"

namespace linksight::cli {
namespace fs = std::filesystem;
namespace {

struct SimulateOptions {
  std::string scene;
  int frames = 0;  // 0: the scene's duration
  std::string out = "out/simulate";
  bool force = false;
  bool quiet = false;
};

int run_simulate(const SimulateOptions& o) {
  const sim::Scene scene = sim::load_scene(o.scene);
  if (o.frames < 0)
    throw std::invalid_argument("--frames = " + std::to_string(o.frames) + ": must be >= 0");
  const int frames = sim::camera_frames(scene, o.frames);
  // The directory appears whole or not at all (a kill or a full disk leaves no part of it).
  io::StagedDir out(o.out, o.force);
  std::unique_ptr<sim::World> world = sim::make_world(scene);
  std::ostringstream truth;
  sim::write_truth_header(truth);
  int contact_frames = 0;
  for (int f = 0; f < frames; ++f) {
    // Frame f is at t = f / fps: step physics up to it (1 kHz by default).
    world->step_until(f / scene.camera.fps);  // frame f is at t = f / fps
    const sim::Truth t = world->truth();
    contact_frames += t.contact ? 1 : 0;
    sim::write_truth_rows(truth, f, t);
  }
  io::write_file_atomic(out.path() / "truth.csv", [&](std::ostream& os) { os << truth.str(); });
  out.commit();
  if (!o.quiet) {
    std::cout << "simulated " << frames << " frames of " << o.scene << " (" << world->time()
              << " s, contact in " << contact_frames << " frames); wrote " << o.out
              << "/truth.csv\n";
  }
  return kExitOk;
}

}  // namespace

Runner add_simulate(CLI::App& app) {
  auto o = std::make_shared<SimulateOptions>();
  app.add_option("--scene", o->scene, "scene file (YAML), e.g. scenes/bend_push.yaml")->required();
  app.add_option("--frames", o->frames, "camera frames to write (0: the scene's duration)")
      ->capture_default_str();
  app.add_option("--out", o->out, "output directory (truth.csv: frame,t_s,node,x_m,y_m,z_m in W)")
      ->capture_default_str();
  app.add_flag("--force", o->force, "replace an existing output directory");
  app.add_flag("--quiet", o->quiet, "print nothing on success");
  return [o] { return run_simulate(*o); };
}

}  // namespace linksight::cli
