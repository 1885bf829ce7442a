#include "linksight/sim/episode.hpp"

#include <algorithm>
#include <chrono>
#include <future>
#include <optional>
#include <stdexcept>
#include <string>

#include "linksight/sim/extract.hpp"
#include "linksight/sim/sensor.hpp"
#include "linksight/sim/world.hpp"
#include "linksight/tracker/format.hpp"
#include "linksight/tracker/seed.hpp"

namespace linksight::sim {
namespace {
double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}
}  // namespace

Eigen::Isometry3d base_prior_error(const Scene& scene) {
  std::uint64_t state = derive_seed(scene.seed, "base_prior");
  const auto normal = [&] {
    const double u1 = unit_interval(splitmix64(state));
    return standard_normal(u1, unit_interval(splitmix64(state)));
  };
  const BasePriorParams& p = scene.tracker.base_prior;
  Eigen::Vector3d dp, dr;
  for (int a = 0; a < 3; ++a) dp[a] = p.sigma_m * normal();
  for (int a = 0; a < 3; ++a) dr[a] = p.sigma_rad * normal();
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.translation() = dp;
  if (dr.norm() > 0) X.linear() = Eigen::AngleAxisd(dr.norm(), dr.normalized()).toRotationMatrix();
  return X;
}

void EpisodeOptions::validate() const {
  if (frames < 0)
    throw std::invalid_argument("episode frames = " + std::to_string(frames) + ": must be >= 0");
  if (threads < 0)
    throw std::invalid_argument("episode threads = " + std::to_string(threads) +
                                ": must be >= 0");
  for (std::size_t i = 0; i < modes.size(); ++i)
    for (std::size_t j = 0; j < i; ++j)
      if (modes[i] == modes[j])
        throw std::invalid_argument("episode modes: " + std::string(to_string(modes[i])) +
                                    " given twice");
  for (std::size_t i = 0; i < external.size(); ++i) {
    for (std::size_t j = 0; j < i; ++j)
      if (external[i].name == external[j].name)
        throw std::invalid_argument("episode external trackers: " + external[i].name +
                                    " given twice");
    for (const TrackerMode m : modes)
      if (to_string(m) == external[i].name)
        throw std::invalid_argument("episode external tracker " + external[i].name +
                                    ": a mode's name");
  }
  if (modes.empty() && !scene_mode && external.empty())
    throw std::invalid_argument("episode: no tracker to run (no mode, no external tracker)");
  score.validate();
}

struct Episode::Impl {
  Scene scene;
  int frames = 0, done = 0;
  std::vector<TrackerMode> modes;
  std::unique_ptr<World> world;
  std::unique_ptr<Sensor> sensor;
  std::vector<Tracker> trackers;
  // After the modes' trackers, in results: the external trackers' processes.
  std::vector<std::unique_ptr<ExternalTracker>> external;
  std::vector<EpisodeScorer> scorers;
  Eigen::Isometry3d X_CW;
  // tracker.base_prior: the error of the base pose the trackers are given, drawn once per
  // episode (a hand-eye calibration error moves with the base), in the base frame.
  std::optional<Eigen::Isometry3d> X_BBprior;
  Nodes previous_C;  // the last frame's true nodes, camera frame
  bool chain_only = false;        // render the chain's box only, but for whole_frames
  int margin_px = 0;              // and that box grown by the segmentation's leakage reach
  std::vector<int> whole_frames;  // sorted
  DepthFrame image;
  Cloud cloud;
  std::optional<DepthView> depth;  // over `image`
  EpisodeFrame out;
  EpisodeTimes times;
  // The next frame's physics, stepping on its own thread while this frame is rendered
  // and tracked: it reads and writes the world only, and the frame holds a copy of the
  // truth, so the result is the same as stepping in turn.
  std::future<void> physics_ahead;
  // A step that threw leaves the world ahead of the frames: no further step.
  bool failed = false;
  // The truth replayed instead of the world (options.replay), or the one being recorded.
  std::shared_ptr<const PhysicsRecording> replay;
  std::shared_ptr<PhysicsRecording> recorded;
};

Episode::Episode(const Scene& scene, const EpisodeOptions& options)
    : impl_(std::make_unique<Impl>()) {
  options.validate();
  Impl& m = *impl_;
  m.scene = scene;
  m.frames = camera_frames(scene, options.frames);
  m.modes = options.modes.empty() && options.scene_mode
                ? std::vector<TrackerMode>{scene.tracker.mode}
                : options.modes;
  if (options.replay) {
    const PhysicsRecording& r = *options.replay;
    if (!(r.fps == scene.camera.fps) || r.frames.size() < static_cast<std::size_t>(m.frames))
      throw std::invalid_argument(
          "episode: the physics recording has " + std::to_string(r.frames.size()) +
          " frames at " + format_shortest(r.fps) + " fps; this episode needs " +
          std::to_string(m.frames) + " at " + format_shortest(scene.camera.fps));
    const auto nodes = static_cast<std::size_t>(scene.chain.geometry.count) + 1;
    if (!r.frames.empty() && r.frames[0].nodes_W.size() != nodes)
      throw std::invalid_argument("episode: the physics recording has a chain of " +
                                  std::to_string(r.frames[0].nodes_W.size()) +
                                  " nodes; this scene's has " + std::to_string(nodes));
    m.replay = options.replay;
  } else {
    m.world = make_world(scene);
    if (options.record) {
      m.recorded = std::make_shared<PhysicsRecording>();
      m.recorded->fps = scene.camera.fps;
      m.recorded->frames.reserve(static_cast<std::size_t>(m.frames));
    }
  }
  m.sensor = make_sensor(scene, options.threads);
  // A tracker that reads the depth image (chain-fit's free-space evidence) reads it
  // anywhere a hidden ball may be held, not only in the true chain's box: whole frames.
  bool reads_depth = false;
  for (const TrackerMode mode : m.modes)
    reads_depth = reads_depth || (mode.spec().update.name == kUpdateChainFit.name &&
                                  scene.tracker.policy.chain_fit.free_space_below > 0);
  // So does an external tracker sent the depth image: it is the camera's whole frame.
  reads_depth = reads_depth || (!options.external.empty() && scene.external.send_depth);
  m.chain_only = options.chain_only_images && !reads_depth &&
                 scene.segmentation.mode == ExtractParams::Mode::truth;
  // Leaked background pixels lie within leakage_px of a link pixel.
  m.margin_px = scene.segmentation.leakage > 0 ? scene.segmentation.leakage_px : 0;
  m.whole_frames = options.whole_frames;
  std::sort(m.whole_frames.begin(), m.whole_frames.end());
  for (const TrackerMode mode : m.modes) {
    TrackerParams p = scene.tracker;
    p.mode = mode;
    m.trackers.emplace_back(p);
    m.scorers.emplace_back(options.score);
  }
  m.X_CW = scene.camera.X_WC.inverse();
  if (scene.tracker.base_prior.enabled) m.X_BBprior = base_prior_error(scene);
  // Started last, after everything that can refuse the scene: a process per tracker.
  for (const ExternalTrackerSpec& spec : options.external) {
    m.external.push_back(std::make_unique<ExternalTracker>(
        spec, scene.external, scene.tracker.nodes, scene.camera.intrinsics,
        scene.tracker.geometry, scene.tracker.base_prior));
    m.external.back()->set_cancel(options.cancel);
    m.scorers.emplace_back(options.score);
  }
}

Episode::~Episode() {
  // Let a step in flight finish before the world goes; its exception has no one to go to.
  if (impl_ && impl_->physics_ahead.valid()) {
    try {
      impl_->physics_ahead.get();
    } catch (...) {  // NOLINT(bugprone-empty-catch): the episode is being destroyed
    }
  }
}

int Episode::frames() const { return impl_->frames; }
int Episode::done() const { return impl_->done; }
const std::vector<TrackerMode>& Episode::modes() const { return impl_->modes; }
std::vector<std::string> Episode::names() const {
  std::vector<std::string> out;
  for (const TrackerMode m : impl_->modes) out.emplace_back(to_string(m));
  for (const auto& e : impl_->external) out.push_back(e->spec().name);
  return out;
}
const EpisodeTimes& Episode::last_times() const { return impl_->times; }
void Episode::stop_external() {
  impl_->external.clear();  // each destructor ends and reaps its process
  impl_->failed = true;
}

const EpisodeFrame& Episode::step() {
  Impl& m = *impl_;
  if (m.done >= m.frames) throw std::logic_error("episode: step() after the last frame");
  if (m.failed) throw std::logic_error("episode: step() after a step that threw");
  try {
    return step_frame();
  } catch (...) {
    m.failed = true;
    throw;
  }
}

const EpisodeFrame& Episode::step_frame() {
  Impl& m = *impl_;
  const int f = m.done;
  const auto frame = static_cast<std::uint64_t>(f);
  auto t0 = std::chrono::steady_clock::now();
  EpisodeFrame& o = m.out;
  o.frame = f;
  if (m.replay) {
    o.truth = m.replay->frames[static_cast<std::size_t>(f)];
  } else if (m.physics_ahead.valid()) {
    m.physics_ahead.get();  // rethrows what the world threw
    o.truth = m.world->truth();
  } else {
    m.world->step_until(f / m.scene.camera.fps);
    o.truth = m.world->truth();
  }
  if (m.recorded) m.recorded->frames.push_back(o.truth);
  if (m.world && f + 1 < m.frames) {
    World* world = m.world.get();
    const double t_next = (f + 1) / m.scene.camera.fps;
    m.physics_ahead = std::async(std::launch::async, [world, t_next] { world->step_until(t_next); });
  }
  o.t = o.truth.t;
  std::swap(m.previous_C, o.truth_C);  // last frame's truth; both buffers are reused
  o.truth_C.resize(o.truth.nodes_W.size());
  for (std::size_t j = 0; j < o.truth_C.size(); ++j) o.truth_C[j] = m.X_CW * o.truth.nodes_W[j];
  o.base_prior_C.reset();
  if (m.X_BBprior) o.base_prior_C = m.X_CW * o.truth.X_WB * *m.X_BBprior;
  o.truth_motion = 0;
  if (f > 0)
    for (std::size_t j = 0; j < o.truth_C.size(); ++j)
      o.truth_motion = std::max(o.truth_motion, (o.truth_C[j] - m.previous_C[j]).norm());
  m.times.physics = seconds_since(t0);

  t0 = std::chrono::steady_clock::now();
  RenderExtent extent;
  extent.chain_only =
      m.chain_only && !std::binary_search(m.whole_frames.begin(), m.whole_frames.end(), f);
  extent.margin_px = m.margin_px;
  m.sensor->render(o.truth.X_WK, o.t, m.scene.seed, frame, m.image, extent);
  m.times.render = seconds_since(t0);
  t0 = std::chrono::steady_clock::now();
  m.cloud = extract_cloud(m.image, m.scene.camera.intrinsics, m.scene.chain.geometry.count,
                          m.scene.segmentation, m.scene.seed, frame);
  m.times.extract = seconds_since(t0);
  o.image = &m.image;
  o.cloud = &m.cloud;
  // The depth image beside the cloud, for chain-fit's free-space evidence (a pinhole
  // camera's: the tracker projects without distortion).
  const io::Intrinsics& K = m.scene.camera.intrinsics;
  m.depth.reset();
  if (K.model == io::Distortion::none && m.image.width > 0)
    m.depth = DepthView{m.image.width, m.image.height, m.image.depth_m, K.fx, K.fy, K.cx, K.cy};

  const std::size_t n_trackers = m.trackers.size() + m.external.size();
  o.results.resize(n_trackers);
  o.scores.resize(n_trackers);
  o.lost_details.assign(n_trackers, std::string());
  // Every tracker's result first, then the scores: an interrupted external tracker
  // leaves no mode with this frame scored and another without.
  for (std::size_t k = 0; k < n_trackers; ++k) {
    // Its own time is in FrameResult::time_s.
    const Eigen::Isometry3d* X_CB = o.base_prior_C ? &*o.base_prior_C : nullptr;
    if (k < m.trackers.size()) {
      o.results[k] = m.trackers[k].step(m.cloud, X_CB, m.depth ? &*m.depth : nullptr);
    } else {
      ExternalTracker& e = *m.external[k - m.trackers.size()];
      o.results[k] = e.step(ExternalFrameInput{f, o.t, &m.cloud, X_CB, &m.image.depth});
      o.lost_details[k] = e.lost_detail();
      // Its SDF metric as a mode's: over the points a tracker keeps.
      if (!o.results[k].lost)
        o.results[k].sdf_error = cloud_sdf_error(m.cloud, o.results[k].nodes,
                                                 m.scene.tracker.geometry);
    }
  }
  double scoring = 0;
  for (std::size_t k = 0; k < n_trackers; ++k) {
    t0 = std::chrono::steady_clock::now();
    const FrameResult& r = o.results[k];
    o.scores[k] = score_frame(r.lost ? Nodes{} : r.nodes, o.truth_C);
    long non_finite = 0;
    for (const Eigen::Vector3d& q : r.nodes) non_finite += !q.allFinite();
    m.scorers[k].add(o.scores[k], r.sdf_error, r.reinit, r.time_s, m.image.link_occluded_fraction,
                     o.truth_motion, non_finite);
    scoring += seconds_since(t0);
  }
  m.times.score = scoring;
  ++m.done;
  return o;
}

std::shared_ptr<const PhysicsRecording> Episode::recording() const {
  const Impl& m = *impl_;
  if (m.done < m.frames) return nullptr;  // a step that threw leaves done short too
  if (m.replay) return m.replay;
  return m.recorded;
}

std::vector<EpisodeSummary> Episode::summaries() const {
  std::vector<EpisodeSummary> s;
  for (const EpisodeScorer& sc : impl_->scorers) s.push_back(sc.summary());
  return s;
}

}  // namespace linksight::sim
