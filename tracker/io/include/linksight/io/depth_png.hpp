#pragma once
/// @file 16-bit depth PNGs and their conversion to clouds.

#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <optional>
#include <vector>

#include "linksight/io/intrinsics.hpp"
#include "linksight/tracker/limits.hpp"
#include "linksight/tracker/cloud.hpp"

namespace linksight::io {

/// Row-major depth in sensor units (0 = no depth).
struct DepthImage {
  int width = 0, height = 0;
  std::vector<std::uint16_t> data;
};

// kMaxDepthPngPixels: linksight/tracker/limits.hpp.

/// A PNG's width, height and bits per sample from its header alone, nothing decoded.
/// Throws InputError naming the file when it is not a PNG.
struct PngSize {
  long long width = 0, height = 0;
  int bit_depth = 0;
};
[[nodiscard]] PngSize png_size(const std::filesystem::path& path);

/// The bytes of the PNG file `path`, checked before a decoder sees them: a regular file,
/// at most kMaxDepthPngSide a side and kMaxDepthPngPixels in all (from the header), at
/// most 4 bytes a pixel of that in the file, every chunk within the file, the first IDAT
/// chunk not empty, and the image data inflating to no more than the header's pixels hold. Throws
/// InputError naming the file and the check. Every PNG reader (depth, labels) decodes only what
/// this returns.
[[nodiscard]] std::vector<char> read_png_checked(const std::filesystem::path& path);

/// Reads a single-channel 16-bit PNG. Throws InputError naming the file when it is not
/// a PNG, not 16-bit or not single-channel, or fails read_png_checked (before anything is
/// decoded).
[[nodiscard]] DepthImage read_depth_png(const std::filesystem::path& path);
/// Writes a 16-bit grayscale PNG (stored deflate blocks), atomically.
void write_depth_png(const std::filesystem::path& path, const DepthImage& image);

struct DepthToCloudOptions {
  double min_depth = 0.0;                                      ///< [m], inclusive
  double max_depth = std::numeric_limits<double>::infinity();  ///< [m], inclusive
  std::optional<Eigen::AlignedBox3d> crop_C;  ///< keep points inside this camera-frame box [m]
  void validate() const;                      ///< throws std::invalid_argument naming the field
};

/// Back-projects every valid pixel. Throws std::invalid_argument when the image size
/// differs from the intrinsics (the caller adds the file name).
[[nodiscard]] Cloud depth_to_cloud(const DepthImage& image, const Intrinsics& intrinsics,
                                   const DepthToCloudOptions& options = {});

}  // namespace linksight::io
