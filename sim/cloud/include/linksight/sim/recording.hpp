#pragma once
/// @file A rendered sequence on disk, laid out like a real recording so that
/// `linksight track --input DIR/depth` reads it as it reads a camera's:
///   DIR/depth/NNNNNN.png     uint16 depth (intrinsics.depth_scale per unit, 0 = none)
///   DIR/labels/NNNNNN.png    uint8 labels (component 0..count-1, 100+k occluder k,
///                            200 background, 255 nothing)
///   DIR/clouds/NNNNNN.ply    the extracted cloud [m, C]
///   DIR/intrinsics.json      the format `linksight track` reads
///   DIR/camera.json          X_WC (4x4 row-major), fps, z range
///   DIR/truth.csv            frame,t_s,node,x_m,y_m,z_m: true nodes in the camera frame
///   DIR/occlusion.csv        frame,component,visible_px,visible_px_unoccluded,occluded_fraction
///   DIR/chain.json           the chain's component geometry (the scene's `chain` keys), for
///                            scoring estimates against the truth (`linksight score`)

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <vector>

#include "linksight/sim/camera.hpp"
#include "linksight/io/atomic_file.hpp"
#include "linksight/sim/sensor.hpp"
#include "linksight/sim/world.hpp"
#include "linksight/tracker/cloud.hpp"
#include "linksight/tracker/geometry.hpp"

namespace linksight::sim {

/// truth.csv: writes the header `frame,t_s,node,x_m,y_m,z_m` and sets 6 decimals.
void write_truth_header(std::ostream& out);
/// Appends one frame's rows of truth.csv: the true nodes mapped into frame F by X_FW.
void write_truth_rows(std::ostream& out, int frame, const Truth& truth,
                      const Eigen::Isometry3d& X_FW = Eigen::Isometry3d::Identity());

/// Writes an 8-bit grayscale PNG atomically. Throws io::InputError naming the path.
void write_label_png(const std::filesystem::path& path, int width, int height,
                     const std::vector<std::uint8_t>& labels);
/// Reads an 8-bit grayscale PNG. Throws io::InputError naming the path.
[[nodiscard]] std::vector<std::uint8_t> read_label_png(const std::filesystem::path& path,
                                                       int& width, int& height);
/// camera.json: {"X_WC": [16 numbers, row-major], "fps", "z_min_m", "z_max_m"}.
void write_camera_json(const std::filesystem::path& path, const CameraParams& camera);

/// camera.json's frame rate [Hz]. Throws io::InputError naming the file for a missing,
/// non-numeric or non-positive fps, or malformed JSON.
[[nodiscard]] double read_camera_fps(const std::filesystem::path& path);

/// chain.json: the component geometry under the scene's `chain` keys (ball_radius_m,
/// pitch_m, neck_radius_m, neck_length_m, count), written atomically.
void write_chain_json(const std::filesystem::path& path, const ComponentGeometry& geometry);
/// Reads chain.json. Throws io::InputError "<file>: <problem>" naming the key for a
/// missing, unknown, non-numeric or out-of-range key, or malformed JSON.
[[nodiscard]] ComponentGeometry read_chain_json(const std::filesystem::path& path);

/// Streams a recording into a staging directory beside `dir`; commit() renames it to
/// `dir` (replacing an old one only when `force`). Without commit() nothing is left.
class Recorder {
 public:
  /// Throws io::InputError when `dir` exists and !force, or cannot be created.
  Recorder(std::filesystem::path dir, const CameraParams& camera,
           const ComponentGeometry& geometry, bool force);
  ~Recorder();
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;

  void write_frame(int frame, const Truth& truth, const DepthFrame& image, const Cloud& cloud);
  void commit();

 private:
  io::StagedDir out_;  // declared first: the streams close before it cleans up
  CameraParams camera_;
  ComponentGeometry geometry_;
  std::ofstream truth_, occlusion_, base_;
};

}  // namespace linksight::sim
