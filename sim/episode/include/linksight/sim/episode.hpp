#pragma once
/// @file An episode: the scene's physics, then at each camera frame the sensor, the
/// cloud, every compared tracker and the scoring. Streams: step() produces one frame and
/// keeps nothing of earlier ones but the scorers' few numbers per frame.

#include <atomic>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "linksight/sim/external_tracker.hpp"
#include "linksight/sim/scene.hpp"
#include "linksight/sim/score.hpp"
#include "linksight/tracker/tracker.hpp"

namespace linksight::sim {

/// The world's truth at every camera frame of one episode, for another episode of the
/// same physics to replay instead of stepping Bullet again (the cells of a sweep whose
/// axes leave the world alone, sweep.hpp's shares_world). Each frame is a copy of what
/// the world gave, so a replay's frames, tracks and scores are the recorded episode's
/// physics bit for bit.
struct PhysicsRecording {
  double fps = 0;            ///< the camera's frame rate it was sampled at [1/s]
  std::vector<Truth> frames; ///< frame f at t = f / fps
};

struct EpisodeOptions {
  int frames = 0;  ///< camera frames to run; 0: the scene's duration
  /// Tracker modes to compare on the same frames; empty: the scene's own mode. Each runs
  /// with the scene's tracker settings and only the mode changed.
  std::vector<TrackerMode> modes;
  /// With no modes: the scene's own mode runs (false: none, only `external`; a --compare
  /// that names external trackers alone).
  bool scene_mode = true;
  /// Trackers outside linksight (issue 18), compared after the modes, in this order: each
  /// started once per episode (a process, docs/protocol.md) with the scene's `external`
  /// settings. Names must differ from each other and from the modes'.
  std::vector<ExternalTrackerSpec> external;
  /// Raised (Ctrl-C): an external tracker's frame stops waiting, and step() throws
  /// ExternalTrackerInterrupted with no frame scored. Not owned; nullptr: never.
  const std::atomic<bool>* cancel = nullptr;
  int threads = 0;  ///< sensor threads (0: the OpenMP default)
  /// When the scene segments by label (ExtractParams::Mode::truth), render only the
  /// pixels the cloud can be made of: the chain's box grown by the leakage margin (see
  /// RenderExtent). Clouds, tracks and scores are the same as with whole frames; the
  /// images outside the box are misses. Ignored for depth segmentation, which reads the
  /// whole image, and when a compared mode reads the depth image (chain-fit's free-space
  /// evidence, tracker.chain_fit.free_space_below > 0).
  bool chain_only_images = false;
  /// Frames rendered whole even so, e.g. those written out as figures.
  std::vector<int> whole_frames;
  ScoreParams score;
  /// Replay this recording's truth instead of running the world (nullptr: run it). The
  /// caller vouches that the scene's chain, world, base and actions are the recorded
  /// episode's (sweep.hpp's shares_world); the episode checks only the frame rate, that
  /// every frame is there and the chain's node count.
  std::shared_ptr<const PhysicsRecording> replay;
  /// Keep every frame's truth, for recording() after the last frame (about 2 kB a frame).
  bool record = false;
  void validate() const;  ///< throws std::invalid_argument naming the field
};

/// Wall time of each stage of the last frame [s]. The physics of frame f + 1 runs on its
/// own thread while frame f is rendered and tracked, so `physics` is only the time step()
/// waited for it (the first frame's: all of it).
struct EpisodeTimes {
  double physics = 0, render = 0, extract = 0, score = 0;
};

/// One camera frame of an episode. Valid until the next step().
struct EpisodeFrame {
  int frame = 0;
  double t = 0;            ///< [s]
  Truth truth;             ///< world frame W
  Nodes truth_C;           ///< the true nodes in the camera frame C [m]
  double truth_motion = 0; ///< largest true node displacement since the last frame [m]
  /// The base pose the trackers were given (scene tracker.base_prior): the true one
  /// with the episode's error (base_prior_error); none when the scene gives none.
  std::optional<Eigen::Isometry3d> base_prior_C;
  const DepthFrame* image = nullptr;
  const Cloud* cloud = nullptr;
  std::vector<FrameResult> results;  ///< per compared tracker (names()), camera frame
  std::vector<FrameScore> scores;    ///< per compared tracker
  /// Per compared tracker, why its frame was lost in words (an external tracker's
  /// malformed answer or its own reason); "" when not lost or a built-in mode's.
  std::vector<std::string> lost_details;
};

/// The error of the base pose an episode gives its trackers (tracker.base_prior): drawn
/// once per episode from the scene's seed, σ sigma_m per axis and sigma_deg about each
/// axis, in the base frame: the prior is X_CB X_BB' with X_BB' this.
[[nodiscard]] Eigen::Isometry3d base_prior_error(const Scene& scene);

class Episode {
 public:
  /// Builds the world, the sensor and one tracker per mode. Throws io::InputError for
  /// a missing mesh, std::invalid_argument for bad options.
  Episode(const Scene& scene, const EpisodeOptions& options);
  ~Episode();
  Episode(const Episode&) = delete;
  Episode& operator=(const Episode&) = delete;

  [[nodiscard]] int frames() const;  ///< frames the episode will run
  [[nodiscard]] int done() const;    ///< frames run so far
  [[nodiscard]] const std::vector<TrackerMode>& modes() const;
  /// Every compared tracker's name, as results are ordered: the modes', then the external
  /// trackers'.
  [[nodiscard]] std::vector<std::string> names() const;
  /// Runs the next frame. Precondition: done() < frames(). After a step that threw (a
  /// tracker, the sensor, the world), the episode is spent: step() throws logic_error. An
  /// external tracker that dies or hangs throws ExternalTrackerError.
  const EpisodeFrame& step();
  [[nodiscard]] const EpisodeTimes& last_times() const;
  /// Ends the external trackers' processes now (as the destructor would): after the last
  /// frame, so that they do not outlive the episode's work. step() may not follow.
  void stop_external();
  /// Per compared tracker (names()), over the frames run so far.
  [[nodiscard]] std::vector<EpisodeSummary> summaries() const;
  /// Once every frame has run: the truth of each, recorded (options.record), or the
  /// recording replayed (options.replay, which may hold more frames); otherwise nullptr.
  [[nodiscard]] std::shared_ptr<const PhysicsRecording> recording() const;

 private:
  const EpisodeFrame& step_frame();
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace linksight::sim
