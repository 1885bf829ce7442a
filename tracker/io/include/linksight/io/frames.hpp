#pragma once
/// @file Frame sequences on disk: a file, a directory or a glob of PLY / depth PNG files.

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "linksight/io/depth_png.hpp"
#include "linksight/io/intrinsics.hpp"
#include "linksight/tracker/cloud.hpp"

namespace linksight::io {

/// Natural order: "frame2" < "frame10".
[[nodiscard]] bool natural_less(const std::string& a, const std::string& b);

/// The frames named by `input`: one file, every *.ply / *.png of a directory, or the
/// matches of a glob pattern; in natural sort order. Throws InputError naming `input`
/// when it names no frame.
[[nodiscard]] std::vector<std::filesystem::path> list_frames(const std::string& input);

/// True for a .png frame, whatever the case of the extension.
[[nodiscard]] bool is_depth_png(const std::filesystem::path& frame);

/// Finds the intrinsics for a depth PNG: `explicit_path` if given, else intrinsics.json
/// beside the frame or in its parent directory. Throws InputError naming the frame.
[[nodiscard]] std::filesystem::path find_intrinsics(
    const std::filesystem::path& frame, const std::optional<std::filesystem::path>& explicit_path);

/// Loads one frame as a cloud: PLY directly, PNG through the intrinsics (and, when
/// `image` is given, the PNG's depth image there; a PLY leaves it empty).
/// Throws InputError naming the file.
[[nodiscard]] Cloud load_frame(const std::filesystem::path& frame, const Intrinsics* intrinsics,
                               const DepthToCloudOptions& options = {},
                               DepthImage* image = nullptr);

}  // namespace linksight::io
