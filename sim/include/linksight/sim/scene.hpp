#pragma once
/// @file Scene files (YAML): the chain, the world, the base trajectory and the actions.
/// YAML is parsed here only; everything else takes the structs. A minimal loader for the
/// physics scenes: every key is known, typed and range-checked, errors name file, line and key.

#include <cstdint>
#include <filesystem>
#include <memory>
#include <vector>

#include "linksight/sim/world.hpp"

namespace linksight::sim {

struct Scene {
  double duration_s = 5.0;  ///< [s]
  std::uint64_t seed = 1;
  double camera_fps = 30.0;  ///< truth is sampled at the camera rate [1/s]
  ChainParams chain;
  WorldParams world;
  BaseTrajectory base;  ///< pose of the base over time (default: identity)
  std::vector<ForceAction> forces;
  std::vector<GravityAction> gravity_switches;
  std::vector<PusherParams> pushers;
  std::vector<ObstacleParams> obstacles;
};

/// Reads a scene; throws linksight::io::InputError "<file>:<line>: <key>: <problem>".
[[nodiscard]] Scene load_scene(const std::filesystem::path& path);

/// Builds the world of a scene at t = 0.
[[nodiscard]] std::unique_ptr<World> make_world(const Scene& scene);

}  // namespace linksight::sim
