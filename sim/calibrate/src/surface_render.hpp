#pragma once
// A recording's frame as a surface in front of the simulated camera: what
// rerender_surfaces returns the depth of, and what fit_noise_rerendered casts once and then
// re-applies noise models to (the sensor's last_noise_input).

#include <cstddef>
#include <cstdint>
#include <memory>

#include "linksight/io/depth_png.hpp"
#include "linksight/io/intrinsics.hpp"
#include "linksight/sim/mesh.hpp"
#include "linksight/sim/noise.hpp"
#include "linksight/sim/sensor.hpp"

namespace linksight::sim {

struct SurfaceRender {
  std::unique_ptr<Sensor> sensor;  // holds the buffers `frame`'s noise input views
  DepthFrame frame;
};

// The camera a surface is rendered with: `K`, at the world's origin.
inline CameraParams surface_camera(const io::Intrinsics& K) {
  CameraParams camera;
  camera.intrinsics = K;
  camera.X_WC = Eigen::Isometry3d::Identity();
  return camera;
}

// Draw `draw` of frame `frame` of `n`: its place in the draw-major list of images and its
// noise frame key, for rerender_surfaces and fit_noise_rerendered alike (draw 0 is the
// frame's own render, key `frame`).
inline std::size_t draw_index(std::size_t n, std::size_t draw, std::size_t frame) {
  return draw * n + frame;
}

// `depth`'s surface (depth_surface_mesh) rendered at `K` with `noise`, draws from (seed,
// frame); the link behind the camera.
SurfaceRender render_surface(const io::DepthImage& depth, const io::Intrinsics& K,
                             const NoiseParams& noise, std::uint64_t seed, std::uint64_t frame,
                             const DepthSurfaceParams& surface);

}  // namespace linksight::sim
