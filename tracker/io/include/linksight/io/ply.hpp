#pragma once
/// @file PLY point clouds: ASCII and binary little-endian; x, y, z as float or double.

#include <filesystem>

#include "linksight/tracker/cloud.hpp"

namespace linksight::io {

/// Reads the vertex x, y, z of a PLY file [m]; other properties and elements are
/// ignored. Throws InputError naming the file for a malformed, truncated or
/// unsupported file.
[[nodiscard]] Cloud read_ply(const std::filesystem::path& path);

/// Writes a binary little-endian PLY with float x, y, z, atomically.
void write_ply(const std::filesystem::path& path, const Cloud& cloud);

}  // namespace linksight::io
