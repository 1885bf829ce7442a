#pragma once
/// @file Scene files (YAML): the chain, the world, the base trajectory and the actions.
/// YAML is parsed here only; everything else takes the structs. A minimal loader for the
/// physics scenes: every key is known, typed and range-checked, errors name file, line and key.

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "linksight/sim/camera.hpp"
#include "linksight/sim/external_tracker.hpp"
#include "linksight/sim/extract.hpp"
#include "linksight/sim/noise.hpp"
#include "linksight/sim/occlusion.hpp"
#include "linksight/sim/sensor.hpp"
#include "linksight/sim/world.hpp"
#include "linksight/tracker/tracker.hpp"

namespace linksight::sim {

struct Scene {
  double duration_s = 5.0;  ///< [s]
  std::uint64_t seed = 1;
  CameraParams camera;  ///< truth and frames are sampled at camera.fps
  NoiseParams noise = NoiseParams::sr300();  ///< preset sr300 unless the scene says otherwise
  /// The listed occluders, then the one `occlusion` generates (when its fraction > 0).
  std::vector<Occluder> occluders;
  ScreenOcclusion occlusion;  ///< as read; its occluder is already in `occluders`
  std::vector<BackgroundObject> background;  ///< table, wall and clutter
  ExtractParams segmentation;
  ChainParams chain;
  WorldParams world;
  BaseTrajectory base;  ///< pose of the base over time (default: identity)
  std::vector<ForceAction> forces;
  std::vector<GravityAction> gravity_switches;
  std::vector<PusherParams> pushers;
  std::vector<ObstacleParams> obstacles;
  /// The tracker run on the scene's frames (key `tracker`). Its geometry and pitch are
  /// the chain's; `--compare` in `linksight run` adds other modes with the same settings.
  TrackerParams tracker;
  /// How long a tracker outside linksight may take (key `external`); which one runs is the
  /// command line's choice only (`--tracker`), never the scene's.
  ExternalParams external;
};

/// Camera frames in the scene: `requested` if > 0, else every frame of duration_s
/// (frame f at t = f / fps, both ends included).
[[nodiscard]] int camera_frames(const Scene& scene, int requested = 0);

/// Reads a scene; mesh files are relative to the scene file's directory. Throws
/// linksight::io::InputError "<file>:<line>: <key>: <problem>".
///
/// `overrides` are "key.path=value" strings (the `--set` of the CLI) applied to the YAML
/// before it is read, so they pass the same checks: "camera.fps=60",
/// "occluders[0].reflectance=0.5", "noise.axial.a_m=0.001", "tracker.mode=accelerated-som".
/// A value is YAML ("[0.1, 0.2, 0.3]" for a vector). Errors in an overridden key name
/// "--set <key>" instead of a line. `axis` are more, applied after them, from a sweep's
/// axes: their errors name "--axis <key>".
[[nodiscard]] Scene load_scene(const std::filesystem::path& path,
                               const std::vector<std::string>& overrides = {},
                               const std::vector<std::string>& axis = {});

/// The scene as load_scene reads it, as YAML that loads to the same Scene: every
/// parameter block (camera, noise, segmentation, chain, world, occlusion, tracker) in
/// full from its field list, the lists (base, occluders, background, actions) as given
/// (mesh files as absolute paths). Every value reads back bit for bit, except an angle
/// set in code in radians that no decimal in degrees maps to exactly: within one ulp.
/// `linksight run --print-scene`. Throws as load_scene.
[[nodiscard]] std::string resolved_scene_yaml(const std::filesystem::path& path,
                                              const std::vector<std::string>& overrides = {});

/// A scene's `noise:` block in full (calibrate-noise's output), from NoiseParams' field
/// list; it loads back to the same NoiseParams (angles: see resolved_scene_yaml).
[[nodiscard]] std::string noise_yaml(const NoiseParams& noise);

/// Builds the world of a scene at t = 0.
[[nodiscard]] std::unique_ptr<World> make_world(const Scene& scene);

/// Builds the scene's camera (with `noise` and `threads`) and its occluders and
/// background. Throws io::InputError for a missing mesh file.
[[nodiscard]] std::unique_ptr<Sensor> make_sensor(const Scene& scene, int threads = 0);

}  // namespace linksight::sim
