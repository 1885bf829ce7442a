#pragma once
/// @file The sensor's last stage on its own: the SR300 noise model applied to noise-free
/// images, with no ray casting. Sensor::render calls it on what Embree cast; calibration
/// or a test can call it on any surface (a plane, a recording's fitted surface).

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "linksight/io/depth_png.hpp"
#include "linksight/sim/camera.hpp"
#include "linksight/sim/lerp_table.hpp"
#include "linksight/sim/noise.hpp"

namespace linksight::sim {

/// How far from a pixel the edge model reads the clean depth [px] (its 2-px band).
inline constexpr int kEdgeReachPx = 2;

/// The noise-free images the noise model reads: row-major, width x height, each of
/// width * height values; read only where depth_m > 0.
struct NoiseInput {
  int width = 0, height = 0;
  std::span<const float> depth_m;        ///< noise-free depth along the ray [m], 0 (or NaN) = nothing hit
  std::span<const float> incidence;      ///< angle of the camera ray to the normal [rad]
  std::span<const float> cos_camera;     ///< its cosine, in [0, 1]
  std::span<const float> cos_projector;  ///< cos of the projector ray to the normal; <= 0: lit from behind
  std::span<const float> reflectance;    ///< of the surface hit, for the low-signal dropout
  std::span<const std::uint8_t> lit;     ///< 1: the projector reaches the point (shadow.enabled)
};

/// The noise model of NoiseParams (axial sigma, correlated noise, dropouts and holes,
/// edge bands and flying pixels, range, quantization) as one stage. Keeps scratch
/// buffers between frames: not thread-safe; apply() is parallel inside.
class SensorNoise {
 public:
  /// Throws std::invalid_argument naming the field of `noise` or `camera` that is bad.
  SensorNoise(const NoiseParams& noise, const CameraParams& camera);

  /// Writes `depth` (sensor units, 0 = none) and `depth_m` ([m], 0 = none; quantized when
  /// noise.quantize) for the pixels in `noisy` (clipped to the image), clearing the rest.
  /// The correlated field is drawn over the hits (depth_m > 0) inside `hits` and `noisy`,
  /// and its values depend on the pixel only, so they are the whole frame's; the edge
  /// rules read the input up to 2 px beyond `noisy`, and drop_steps sees nothing beyond it
  /// (Sensor passes a `noisy` box inside the cast, so that its pixels are the whole frame's
  /// render). Draws come from (seed, frame)
  /// and the pixel index only: the same for any thread count (`threads` 0: the OpenMP
  /// default). Throws std::invalid_argument when the input's size is not the camera's.
  void apply(const NoiseInput& in, std::uint64_t seed, std::uint64_t frame,
             const PixelBox& noisy, const PixelBox& hits, int threads, io::DepthImage& depth,
             std::vector<float>& depth_m);
  /// The whole image.
  void apply(const NoiseInput& in, std::uint64_t seed, std::uint64_t frame, int threads,
             io::DepthImage& depth, std::vector<float>& depth_m);

  /// Steps of theta over [0, theta_cap] in the angle term's table (a power other than 2,
  /// the two fields apart, a cap of at least a microradian).
  static constexpr std::size_t kAngleTableSteps = 4096;

 private:
  NoiseParams noise_;
  CameraParams camera_;
  // Correlated axial noise, set at set-up: the pixel-scale term's kernels along rows and
  // columns, and the low-frequency term's (empty when it is off).
  std::vector<float> rows_kernel_, cols_kernel_, low_rows_kernel_, low_cols_kernel_;
  std::vector<float> white_, blurred_, field_, low_field_;  // their per-frame buffers
  std::vector<float> along_u_;  // the low field's grid rows, interpolated along u
  // AxialNoise::pixel_depth_factor every 0.5 mm or less over its range (within 1e-6 of
  // it, relative, for the preset); empty when the power does nothing (0, or the two fields
  // not apart).
  LerpTable pixel_factor_;
  // The angle term's q^angle_power (AxialNoise::Point) at kAngleTableSteps steps of theta over [0,
  // theta_cap] (within 1e-4 of std::pow, relative, from 1 to 75 degrees for a cap of 80; within 2%
  // at a cap of 89.9, where q grows without bound). Empty for the power 2 (q * q, the images from
  // before the power) and without the two fields apart.
  LerpTable angle_power_;
  std::vector<std::uint8_t> hole_;            // per pixel: inside a dropout hole
  std::vector<std::uint16_t> steps_;          // the reported depth, for edges.drop_steps
  std::vector<std::uint16_t> none_;           // a row of pixels that report nothing
  int step_units_ = 1;  // edges.drop_steps: the least depth difference [units] over the jump
  std::vector<int> blob_;                     // the hole being grown
  std::vector<std::uint32_t> blob_stamp_;     // per pixel: the id of the last blob it joined
  std::uint32_t blob_id_ = 0;
};

}  // namespace linksight::sim
