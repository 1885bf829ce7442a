#pragma once
/// @file The simulated SR300: Embree casts the chain, occluders and background into a
/// depth image with per-pixel labels, then the noise model adds the camera's errors.

#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <memory>
#include <string_view>
#include <vector>

#include "linksight/io/depth_png.hpp"
#include "linksight/tracker/limits.hpp"
#include "linksight/sim/camera.hpp"
#include "linksight/sim/mesh.hpp"
#include "linksight/sim/noise.hpp"
#include "linksight/sim/sensor_noise.hpp"
#include "linksight/sim/trajectory.hpp"
#include "linksight/tracker/fields.hpp"
#include "linksight/tracker/geometry.hpp"

namespace linksight::sim {

/// Label image values: component index 0..count-1, then these.
inline constexpr std::uint8_t kLabelOccluder0 = 100;   ///< occluder k has 100 + k
inline constexpr std::uint8_t kLabelBackground = 200;  ///< table, wall, clutter
inline constexpr std::uint8_t kLabelNothing = 255;     ///< the ray hit nothing
// kMaxOccluders: linksight/tracker/limits.hpp.

enum class ShapeKind { box, cylinder, sphere, mesh };
/// "box", "cylinder", "sphere", "mesh"; parse throws std::invalid_argument naming the
/// value and the choices.
[[nodiscard]] std::string_view to_string(ShapeKind kind);
[[nodiscard]] ShapeKind parse_shape_kind(std::string_view name);

/// A rigid shape in its own frame O (centred at the origin).
struct Shape {
  using Kind = ShapeKind;
  Kind kind = Kind::box;
  Eigen::Vector3d half_extents = Eigen::Vector3d(0.05, 0.05, 0.05);  ///< box [m]
  double radius = 0.05;                  ///< cylinder (around z) and sphere [m]
  double half_length = 0.05;             ///< cylinder, along z [m]
  std::filesystem::path mesh;            ///< mesh: any file assimp reads
  /// mesh: the triangles in memory, in file units: used instead of reading `mesh` (a scene
  /// keeps what it read at load, so each file is read once), or alone when `mesh` is empty
  std::shared_ptr<const TriangleMesh> mesh_data;
  double scale = 1.0;                    ///< mesh: file units to metres
  /// The keys of a shaped item (occluders, background objects; fields.hpp); `mesh` is
  /// read as a path relative to the scene file, not a field.
  template <class Archive>
  void fields(Archive& ar) {
    ar("shape", kind, parse_shape_kind);
    ar("half_extents_m", half_extents);  // all > 0
    ar("radius_m", radius, fields::in(1e-4, 10));
    ar("half_length_m", half_length, fields::in(1e-4, 10));
    ar("scale", scale, fields::in(1e-6, 1e6));
  }
  void validate() const;  ///< throws fields::FieldError naming the key
  /// The triangles; throws linksight::io::InputError naming a missing or bad mesh file.
  [[nodiscard]] TriangleMesh triangles() const;
};


/// Something between the camera and the link, moving along a scripted pose path.
struct Occluder {
  Shape shape;
  BaseTrajectory path;       ///< pose X_WO over time
  double reflectance = 1.0;  ///< for the low-signal dropout proxy
  /// The keys of an `occluders` item (fields.hpp): the shape's and these; `path`,
  /// `from_s` and `to_s` (either may be absent: always there) are read, not fields.
  template <class Archive>
  void fields(Archive& ar) {
    shape.fields(ar);
    ar("reflectance", reflectance, fields::in(0, 10));
  }
  /// In the scene only while from_s <= t < to_s [s]; outside it neither hides nor shadows.
  double from_s = -std::numeric_limits<double>::infinity();
  double to_s = std::numeric_limits<double>::infinity();
  /// Throws fields::FieldError naming the key: the shape's, reflectance, from_s in
  /// [0, 1e6] s and to_s in (0, 1e6] s (or open: -inf, +inf), to_s > from_s.
  void validate() const;
  /// Times within 1 us count as equal: a frame's time comes from the physics clock
  /// (steps x dt), which need not equal f / fps to the last bit.
  [[nodiscard]] bool present(double t) const {
    constexpr double kSlack = 1e-6;
    return t >= from_s - kSlack && t < to_s - kSlack;
  }
};

/// Static scenery: table, wall, clutter.
struct BackgroundObject {
  Shape shape;
  Eigen::Isometry3d X_WO = Eigen::Isometry3d::Identity();
  double reflectance = 1.0;
  /// The keys of a `background.objects` item (fields.hpp): the shape's and reflectance;
  /// the pose is read from position_m and rpy_deg.
  template <class Archive>
  void fields(Archive& ar) {
    shape.fields(ar);
    ar("reflectance", reflectance, fields::in(0, 10));
  }
};

struct SensorParams {
  CameraParams camera;
  NoiseParams noise = NoiseParams::sr300();
  double chain_reflectance = 1.0;
  int component_segments = 96;  ///< mesh resolution of a ball: 0.01 mm sagitta at r = 15 mm
  int threads = 0;              ///< OpenMP threads; 0: the OpenMP default
  /// Skip the pixels whose rays provably miss every object (outside the projection of the
  /// objects' bounding box, widened by the largest jitter). Exact: the images are the same
  /// with it off, only slower. Applies to the pinhole camera only.
  bool cull = true;
  void validate() const;        ///< throws std::invalid_argument naming the field
};

/// Which pixels render() computes.
struct RenderExtent {
  /// Only the pixels the chain can be seen in (its bounds' projection, widened by the
  /// largest jitter), grown by `margin_px`. Inside, the images are those of a whole-frame
  /// render, bit for bit; depth and depth_m hold a miss everywhere else. The noise-free
  /// images (depth_clean_m, label, incidence) are cast 2 px further, as far as the edge
  /// model reads, and hold a miss beyond that. What a label-segmented cloud needs, at a fraction of the cost of
  /// a frame where every ray hits the background.
  bool chain_only = false;
  int margin_px = 0;  ///< [px], >= 0; cover ExtractParams::leakage_px
};

/// One rendered frame. Images are row-major, width x height.
struct DepthFrame {
  int width = 0, height = 0;
  /// The pixels rendered: the whole image, or the chain's box (RenderExtent::chain_only).
  /// Outside it, depth and depth_m hold a miss (the noise-free images reach 2 px further).
  PixelBox rendered;
  io::DepthImage depth;               ///< sensor units (intrinsics.depth_scale), 0 = none
  std::vector<float> depth_m;         ///< [m], 0 = none (quantized when noise.quantize)
  std::vector<float> depth_clean_m;   ///< noise-free depth along the cast ray [m], 0 = nothing hit
  std::vector<std::uint8_t> label;    ///< what the ray hit (see kLabel*)
  std::vector<float> incidence;       ///< incidence angle at the camera [rad], NaN where nothing hit
  std::vector<int> visible_px;        ///< per component: pixels labelled with it
  std::vector<int> visible_px_unoccluded;  ///< the same without occluders
  /// Per component: 1 - visible / unoccluded (0 when not visible even without occluders).
  std::vector<double> occluded_fraction;
  double link_occluded_fraction = 0.0;  ///< the same over all components
};

/// Time of each stage of the last render [s].
struct SensorTimes {
  double scene = 0, cast = 0, occlusion = 0, noise = 0;
};

/// Owns the Embree device and scene. One chain (one mesh, `count` instances), the
/// occluders and the background. Not thread-safe; render() is parallel inside.
class Sensor {
 public:
  /// Throws std::invalid_argument for bad parameters, io::InputError for a missing mesh.
  Sensor(const SensorParams& params, const ComponentGeometry& geometry,
         std::vector<Occluder> occluders = {}, std::vector<BackgroundObject> background = {});
  ~Sensor();
  Sensor(const Sensor&) = delete;
  Sensor& operator=(const Sensor&) = delete;

  /// Renders the instant `t` [s]: component frames X_WK (count of them) [W], occluders
  /// at their path poses. Noise draws come from (seed, frame) and the pixel index only,
  /// so the result is the same for any thread count. Reuses `out`'s buffers. Throws
  /// std::invalid_argument for a negative extent margin.
  void render(const std::vector<Eigen::Isometry3d>& X_WK, double t, std::uint64_t seed,
              std::uint64_t frame, DepthFrame& out, const RenderExtent& extent = {});
  [[nodiscard]] DepthFrame render(const std::vector<Eigen::Isometry3d>& X_WK, double t,
                                  std::uint64_t seed, std::uint64_t frame,
                                  const RenderExtent& extent = {});

  [[nodiscard]] const SensorParams& params() const;
  [[nodiscard]] const SensorTimes& last_times() const;
  /// What the noise stage read in the last render into `frame`: views into `frame` and
  /// into the sensor's scratch, valid until the next render. SensorNoise::apply on it
  /// gives that render's depth again.
  [[nodiscard]] NoiseInput last_noise_input(const DepthFrame& frame) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace linksight::sim
