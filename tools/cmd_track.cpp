// linksight track: clouds in, nodes.csv + frames.csv + summary.json out.
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <map>
#include <optional>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

#include "cli_common.hpp"
#include "commands.hpp"
#include "format.hpp"
#include "linksight/io/atomic_file.hpp"
#include "linksight/io/base_pose.hpp"
#include "linksight/io/error.hpp"
#include "linksight/io/frames.hpp"
#include "linksight/tracker/opencl.hpp"
#include "linksight/tracker/tracker.hpp"
#include "params_json.hpp"

namespace linksight::cli {
namespace fs = std::filesystem;
namespace {

struct TrackOptions {
  std::string input;
  std::string intrinsics;
  std::string mode = "chain-fit";
  std::string init = "pca";
  std::string som_init = "straight-line";
  std::string backend = "serial";
  std::string cl_device;
  int cl_platform = -1;
  std::string cl_accumulation = "reduction";
  std::size_t cl_work_group = 0;
  int threads = 0;
  int nodes = 12;
  int iterations = 4;
  int poly_order = 3;
  double pitch = 0.045;
  double min_depth = 0.0;
  double max_depth = std::numeric_limits<double>::infinity();
  std::vector<double> crop;
  std::string lost_frames = "error";
  std::string base_prior;
  bool base_prior_sigma_given = false;  // either sigma flag on the command line
  double base_prior_sigma_m = BasePriorParams{}.sigma_m;
  double base_prior_sigma_deg = BasePriorParams{}.sigma_rad * 180 / 3.14159265358979323846;
  std::uint64_t seed = 0;
  std::string out = "out/track";
  bool quiet = false;
};

int run_track(const TrackOptions& o) {
  TrackerParams p;
  p.mode = parse_mode(o.mode);
  p.policy.lsq_init.method = parse_init(o.init);
  try {
    p.policy.som_init.method = parse_som_init(o.som_init);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("--som-init: ") + e.what());
  }
  if (o.backend == "auto") {
    p.backend = auto_backend();
    if (!o.quiet) {
      std::cerr << "linksight: --backend auto picked " << to_string(p.backend)
                << (p.backend == BackendKind::opencl ? " (a GPU OpenCL device is present)\n"
                                                     : " (no GPU OpenCL device found)\n");
    }
  } else {
    p.backend = parse_backend(o.backend);
  }
  // The environment names the device only when the flag does not.
  p.opencl.device = o.cl_device;
  if (p.opencl.device.empty()) {
    if (const char* env = std::getenv("LINKSIGHT_CL_DEVICE")) p.opencl.device = env;
  }
  p.opencl.platform = o.cl_platform;
  try {
    p.opencl.accumulation = parse_cl_accumulation(o.cl_accumulation);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("--cl-accumulation: ") + e.what());
  }
  p.opencl.work_group_size = o.cl_work_group;
  p.threads = o.threads;
  p.nodes = o.nodes;
  p.iterations = o.iterations;
  p.policy.lsq_init.poly_order = o.poly_order;
  p.policy.lsq_init.pitch = o.pitch;
  p.geometry.pitch = o.pitch;
  p.policy.som_init.seed = o.seed;
  p.base_prior.enabled = !o.base_prior.empty();
  p.base_prior.sigma_m = o.base_prior_sigma_m;
  p.base_prior.sigma_rad = o.base_prior_sigma_deg * 3.14159265358979323846 / 180;
  if (o.base_prior_sigma_given && o.base_prior.empty())
    throw std::invalid_argument("--base-prior-sigma-m/--base-prior-sigma-deg: need --base-prior");
  try {
    p.base_prior.validate();
  } catch (const fields::FieldError& e) {  // name the flag that set it
    throw std::invalid_argument("--base-prior-" +
                                std::string(e.key() == "sigma_m" ? "sigma-m" : "sigma-deg") +
                                " " + e.value() + ": " + e.rule());
  }
  p.validate();
  if (o.lost_frames != "error" && o.lost_frames != "keep") {
    throw std::invalid_argument("--lost-frames: unknown value '" + o.lost_frames +
                                "' (error or keep)");
  }
  io::DepthToCloudOptions depth;
  depth.min_depth = o.min_depth;
  depth.max_depth = o.max_depth;
  if (!o.crop.empty()) {
    if (o.crop.size() != 6)
      throw std::invalid_argument("--crop: need 6 values xmin,ymin,zmin,xmax,ymax,zmax");
    depth.crop_C = Eigen::AlignedBox3d(Eigen::Vector3d(o.crop[0], o.crop[1], o.crop[2]),
                                       Eigen::Vector3d(o.crop[3], o.crop[4], o.crop[5]));
  }
  depth.validate();

  const std::vector<fs::path> frames = io::list_frames(o.input);
  // Read whole before anything is written: a bad row leaves no output.
  std::vector<Eigen::Isometry3d> base_poses;
  if (!o.base_prior.empty()) base_poses = io::read_base_poses(o.base_prior, frames.size());
  std::optional<fs::path> explicit_intrinsics;
  if (!o.intrinsics.empty()) explicit_intrinsics = fs::path(o.intrinsics);
  std::map<fs::path, io::Intrinsics> intrinsics_cache;

  // A failed run leaves nothing behind: not even the output directory it created.
  std::error_code ec;
  const fs::path out_dir(o.out);
  const bool created_out = !fs::exists(out_dir, ec);
  fs::create_directories(out_dir, ec);
  if (ec) throw io::InputError(o.out + ": cannot create output directory: " + ec.message());
  struct RemoveIfFailed {
    fs::path dir;
    bool armed;
    ~RemoveIfFailed() {
      std::error_code ignored;
      if (armed && fs::is_empty(dir, ignored)) fs::remove(dir, ignored);
    }
  } cleanup{out_dir, created_out};
  io::StagedFiles staged;
  std::ostream& nodes_csv = staged.open(fs::path(o.out) / "nodes.csv");
  std::ostream& frames_csv = staged.open(fs::path(o.out) / "frames.csv");
  nodes_csv << "frame,node,x_m,y_m,z_m,n_points\n";
  frames_csv
      << "frame,n_points,iterations,reinit,lost,time_ms,sdf_err_mm,n_non_finite,n_out_of_range,"
         "init_reason,lost_reason,device_ms,file\n";

  Tracker tracker(p);
  std::vector<float> depth_m;  // the frame's depth image in metres, when it is one
  std::size_t lost = 0, reinits = 0;
  double time_sum = 0, sdf_sum = 0;
  std::size_t sdf_n = 0;
  for (std::size_t f = 0; f < frames.size(); ++f) {
    const fs::path& path = frames[f];
    const io::Intrinsics* k = nullptr;
    if (io::is_depth_png(path)) {
      const fs::path kp = io::find_intrinsics(path, explicit_intrinsics);
      auto it = intrinsics_cache.find(kp);
      if (it == intrinsics_cache.end())
        it = intrinsics_cache.emplace(kp, io::read_intrinsics(kp)).first;
      k = &it->second;
    }
    io::DepthImage image;
    const Cloud cloud = io::load_frame(path, k, depth, &image);
    // A depth PNG's whole image (not only the cloud cut from it) is chain-fit's evidence
    // of free space, for a pinhole camera (the fit projects without distortion).
    std::optional<DepthView> view;
    if (k != nullptr && k->model == io::Distortion::none && !image.data.empty()) {
      depth_m.resize(image.data.size());
      for (std::size_t i = 0; i < image.data.size(); ++i)
        depth_m[i] = static_cast<float>(image.data[i] * k->depth_scale);
      view = DepthView{image.width, image.height, depth_m, k->fx, k->fy, k->cx, k->cy};
    }
    const FrameResult r = tracker.step(cloud, base_poses.empty() ? nullptr : &base_poses[f],
                                       view ? &*view : nullptr);
    if (r.n_out_of_range > 0 && !r.lost) {
      std::cerr << "linksight: " << io::echo(path.string(), io::kMaxMessage) << ": dropped "
                << r.n_out_of_range << " points beyond " << kMaxCoordinate << " m\n";
    }
    if (r.n_non_finite > 0 && !r.lost) {
      std::cerr << "linksight: " << io::echo(path.string(), io::kMaxMessage) << ": dropped "
                << r.n_non_finite << " non-finite points\n";
    }
    if (r.lost) {
      const std::string why =
          path.string() + ": frame lost (" + std::string(to_string(r.lost_reason)) + ", " +
          std::to_string(r.n_points) + " finite points, " + std::to_string(p.nodes) + " nodes)";
      if (o.lost_frames == "error") throw io::InputError(why);
      std::cerr << "linksight: " << io::printable_line(why) << "\n";
      ++lost;
    }
    reinits += r.reinit ? 1 : 0;
    time_sum += r.time_s;
    if (std::isfinite(r.sdf_error)) {
      sdf_sum += r.sdf_error;
      ++sdf_n;
    }
    for (std::size_t j = 0; j < r.nodes.size(); ++j) {
      nodes_csv << f << ',' << j << ',' << format_fixed(r.nodes[j].x(), 6) << ',' << format_fixed(r.nodes[j].y(), 6)
                << ',' << format_fixed(r.nodes[j].z(), 6) << ',' << r.counts[j] << '\n';
    }
    frames_csv << f << ',' << r.n_points << ',' << r.iterations << ',' << (r.reinit ? 1 : 0) << ','
               << (r.lost ? 1 : 0) << ',' << format_fixed(r.time_s * 1e3, 4) << ','
               << format_fixed(r.sdf_error * 1e3, 4) << ',' << r.n_non_finite << ',' << r.n_out_of_range
               << ',' << to_string(r.init_reason) << ',' << to_string(r.lost_reason) << ','
               << format_fixed(r.device_time_s * 1e3, 4) << ',' << path.filename().string() << '\n';
  }
  const double mean_ms = frames.empty() ? 0 : time_sum * 1e3 / static_cast<double>(frames.size());
  const double mean_sdf_mm = sdf_n ? sdf_sum * 1e3 / static_cast<double>(sdf_n) : std::nan("");
  // The tracker's settings under the scene's `tracker` keys, then what the command adds.
  nlohmann::json params = to_json(p);
  params["cl_device"] = p.opencl.device;
  params["cl_accumulation"] = o.cl_accumulation;
  params["nodes"] = p.nodes;
  params["pitch_m"] = p.policy.lsq_init.pitch;
  params["seed"] = p.policy.som_init.seed;
  params["base_prior_file"] = o.base_prior;
  nlohmann::json summary = {
      {"input", o.input},
      {"frames", frames.size()},
      {"lost_frames", lost},
      {"reinit_frames", reinits},
      {"mean_time_ms", mean_ms},
      {"mean_sdf_err_mm", sdf_n ? nlohmann::json(mean_sdf_mm) : nlohmann::json(nullptr)},
      {"params", params}};
  // File names need not be UTF-8: replace what JSON cannot hold rather than fail.
  staged.open(fs::path(o.out) / "summary.json")
      << summary.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) << "\n";
  staged.commit();
  cleanup.armed = false;
  if (!o.quiet) {
    std::cout << "tracked " << frames.size() << " frames (" << lost << " lost, " << reinits
              << " re-initialized) with " << to_string(p.mode) << "/" << o.init << " on "
              << to_string(p.backend) << ": " << format_fixed(mean_ms, 3) << " ms/frame, mean SDF error "
              << format_fixed(mean_sdf_mm, 2) << " mm\nwrote " << o.out
              << "/{nodes.csv,frames.csv,summary.json}\n";
  }
  return kExitOk;
}

}  // namespace

Runner add_track(CLI::App& app) {
  auto o = std::make_shared<TrackOptions>();
  app.add_option("--input", o->input,
                 "Frames: a .ply/.png file, a directory (natural order) or a glob")
      ->required();
  app.add_option("--intrinsics", o->intrinsics,
                 "intrinsics.json for depth PNGs (default: beside the frames or in their parent)");
  app.add_option("--mode", o->mode, mode_choices())->capture_default_str();
  app.add_option("--init", o->init, "LSQ init of paper mode: paper | pca")->capture_default_str();
  app.add_option("--som-init", o->som_init,
                 "init of accelerated-som mode: straight-line | random-sample")
      ->capture_default_str();
  app.add_option(
         "--backend", o->backend,
         "serial | openmp | opencl | auto (opencl if a GPU OpenCL device exists, else openmp)")
      ->capture_default_str();
  app.add_option(
      "--cl-device", o->cl_device,
      "opencl: case-insensitive substring of the device name (default: env "
      "LINKSIGHT_CL_DEVICE, else the first GPU, else the first device); see 'linksight devices'");
  app.add_option("--cl-platform", o->cl_platform, "opencl: platform index (-1: any)")
      ->capture_default_str();
  app.add_option(
         "--cl-accumulation", o->cl_accumulation,
         "opencl: reduction (per-work-group partial sums) | atomic (the paper's global atomics)")
      ->capture_default_str();
  // Checked here as well as by OpenCLOptions::validate: CLI11 would wrap -1 to 2^64 - 1,
  // and the library's message would name that instead of what was typed.
  app.add_option("--cl-work-group", o->cl_work_group, "opencl: work-group size (0: auto)")
      ->check(CLI::Range(std::size_t{0}, kMaxClWorkGroupSize))
      ->capture_default_str();
  app.add_option("--threads", o->threads, "threads of parallel back ends (0: one per core)")
      ->capture_default_str();
  app.add_option("--nodes", o->nodes, "reference vectors M+1")->capture_default_str();
  app.add_option("--iterations", o->iterations, "SOM iterations per frame")->capture_default_str();
  app.add_option("--poly-order", o->poly_order, "LSQ polynomial order")->capture_default_str();
  app.add_option("--pitch", o->pitch, "component pitch [m] (pca init spacing, SDF geometry)")
      ->capture_default_str();
  app.add_option("--min-depth", o->min_depth, "depth PNG: drop depth below this [m]")
      ->capture_default_str();
  app.add_option("--max-depth", o->max_depth, "depth PNG: drop depth above this [m]");
  app.add_option("--crop", o->crop,
                 "depth PNG: keep points in the camera-frame box xmin,ymin,zmin,xmax,ymax,zmax [m]")
      ->delimiter(',')
      ->expected(6);
  app.add_option(
         "--lost-frames", o->lost_frames,
         "error: a lost frame (empty, all non-finite, fewer points than nodes) aborts with exit 2; "
         "keep: record it (lost=1) and go on")
      ->capture_default_str();
  add_seed_option(app, o->seed, "seed of random-sample init");
  app.add_option("--base-prior", o->base_prior,
                 "chain-fit: the base's pose per frame, a CSV frame,x_m,y_m,z_m,qw,qx,qy,qz "
                 "(X_CB, camera frame; frame = index in the input's order; as render's "
                 "base_pose.csv)");
  CLI::Option* sigma_m = app.add_option("--base-prior-sigma-m", o->base_prior_sigma_m,
                                        "with --base-prior: the pose's position sigma [m]")
                             ->capture_default_str();
  CLI::Option* sigma_deg =
      app.add_option("--base-prior-sigma-deg", o->base_prior_sigma_deg,
                     "with --base-prior: the pose's orientation sigma [deg]")
          ->capture_default_str();
  app.add_option("--out", o->out, "output directory")->capture_default_str();
  app.add_flag("--quiet", o->quiet, "print nothing on success");
  return [o, sigma_m, sigma_deg] {
    o->base_prior_sigma_given = sigma_m->count() + sigma_deg->count() > 0;
    return run_track(*o);
  };
}

}  // namespace linksight::cli
