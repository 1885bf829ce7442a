// linksight synth: a small synthetic cloud sequence with its truth, for the demo and
// for trying the tracker before the simulator exists.
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <sstream>

#include "cli_common.hpp"
#include "commands.hpp"
#include "linksight/io/atomic_file.hpp"
#include "linksight/io/error.hpp"
#include "linksight/io/ply.hpp"
#include "linksight/sim/synthetic_chain.hpp"
#include "linksight/tracker/limits.hpp"
#include "linksight/tracker/seed.hpp"

namespace linksight::cli {
namespace fs = std::filesystem;
namespace {

struct SynthOptions {
  std::string out = "out/synth";
  int frames = 60;
  double fps = 30.0;
  double noise = 0.001;
  int samples_per_ball = 1200;
  std::uint64_t seed = 1;
  bool force = false;
  bool quiet = false;
};

// kMaxSamplesPerBall, kMaxSynthFrames: linksight/tracker/limits.hpp.
using sim::kMaxSamplesPerBall;
using sim::kMaxSynthFrames;

int run_synth(const SynthOptions& o) {
  if (o.frames < 1 || o.frames > kMaxSynthFrames)
    throw std::invalid_argument("--frames = " + std::to_string(o.frames) + ": must be in [1, " +
                                std::to_string(kMaxSynthFrames) + "]");
  if (!(o.fps > 0)) throw std::invalid_argument("--fps: must be > 0");
  if (o.samples_per_ball < 1 || o.samples_per_ball > kMaxSamplesPerBall)
    throw std::invalid_argument("--samples-per-ball = " + std::to_string(o.samples_per_ball) +
                                ": must be in [1, " + std::to_string(kMaxSamplesPerBall) + "]");
  if (!(o.noise >= 0 && o.noise <= 1))
    throw std::invalid_argument("--noise: must be in [0, 1] m");
  const ComponentGeometry g;
  // The directory appears whole or not at all: a kill or a full disk leaves no frames of a
  // sequence under the final name, and a re-run with fewer frames no stale ones.
  io::StagedDir out(o.out, o.force);
  std::ostringstream truth;
  truth << "frame,node,x_m,y_m,z_m\n" << std::fixed << std::setprecision(6);
  for (int f = 0; f < o.frames; ++f) {
    const Nodes nodes = sim::demo_nodes(g, f, o.fps);
    sim::SurfaceSampling s;
    s.noise_sigma = o.noise;
    s.samples_per_ball = o.samples_per_ball;
    s.seed = derive_seed(o.seed, static_cast<std::uint64_t>(f));  // by frame, not call order
    const Cloud cloud = sim::sample_visible_surface(nodes, g, s);
    std::ostringstream name;
    name << "frame_" << std::setw(4) << std::setfill('0') << f << ".ply";
    io::write_ply(out.path() / name.str(), cloud);
    for (std::size_t j = 0; j < nodes.size(); ++j) {
      truth << f << ',' << j << ',' << nodes[j].x() << ',' << nodes[j].y() << ',' << nodes[j].z()
            << '\n';
    }
  }
  io::write_file_atomic(out.path() / "truth.csv", [&](std::ostream& os) { os << truth.str(); });
  out.commit();
  if (!o.quiet) {
    std::cout << "wrote " << o.frames << " frames and truth.csv to " << o.out << "\n";
  }
  return kExitOk;
}

}  // namespace

Runner add_synth(CLI::App& app) {
  auto o = std::make_shared<SynthOptions>();
  app.add_option("--out", o->out, "output directory")->capture_default_str();
  app.add_option("--frames", o->frames, "number of frames")->capture_default_str();
  app.add_option("--fps", o->fps, "frame rate [1/s]")->capture_default_str();
  app.add_option("--noise", o->noise, "axial Gaussian noise sigma [m]")->capture_default_str();
  app.add_option("--samples-per-ball", o->samples_per_ball, "surface samples drawn per ball")
      ->capture_default_str();
  add_seed_option(app, o->seed,
                  "seed of the surface samples and their noise (each frame its own, derived)");
  app.add_flag("--force", o->force, "replace an existing output directory");
  app.add_flag("--quiet", o->quiet, "print nothing on success");
  return [o] { return run_synth(*o); };
}

}  // namespace linksight::cli
