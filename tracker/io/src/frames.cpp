#include "linksight/io/frames.hpp"

#include <glob.h>

#include <algorithm>
#include <cctype>

#include "linksight/io/error.hpp"
#include "linksight/io/ply.hpp"

namespace linksight::io {
namespace fs = std::filesystem;
namespace {
std::string lower_ext(const fs::path& p) {
  std::string e = p.extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return std::tolower(c); });
  return e;
}
bool is_frame(const fs::path& p) {
  const std::string e = lower_ext(p);
  return e == ".ply" || e == ".png";
}
}  // namespace

bool is_depth_png(const fs::path& frame) { return lower_ext(frame) == ".png"; }

bool natural_less(const std::string& a, const std::string& b) {
  std::size_t i = 0, j = 0;
  while (i < a.size() && j < b.size()) {
    if (std::isdigit(static_cast<unsigned char>(a[i])) &&
        std::isdigit(static_cast<unsigned char>(b[j]))) {
      std::size_t i2 = i, j2 = j;
      while (i2 < a.size() && std::isdigit(static_cast<unsigned char>(a[i2]))) ++i2;
      while (j2 < b.size() && std::isdigit(static_cast<unsigned char>(b[j2]))) ++j2;
      // Compare digit runs by value: strip leading zeros, then length, then digits.
      std::size_t ia = i, jb = j;
      while (ia + 1 < i2 && a[ia] == '0') ++ia;
      while (jb + 1 < j2 && b[jb] == '0') ++jb;
      if (i2 - ia != j2 - jb) return i2 - ia < j2 - jb;
      const int c = a.compare(ia, i2 - ia, b, jb, j2 - jb);
      if (c != 0) return c < 0;
      if (i2 - i != j2 - j) return i2 - i < j2 - j;  // "01" after "1"
      i = i2;
      j = j2;
    } else {
      if (a[i] != b[j]) return a[i] < b[j];
      ++i;
      ++j;
    }
  }
  return a.size() - i < b.size() - j;
}

std::vector<fs::path> list_frames(const std::string& input) {
  std::vector<fs::path> out;
  std::error_code ec;
  if (input.find_first_of("*?[") != std::string::npos && !fs::exists(input, ec)) {
    glob_t g{};
    if (::glob(input.c_str(), 0, nullptr, &g) == 0) {
      for (std::size_t i = 0; i < g.gl_pathc; ++i) {
        if (fs::is_regular_file(g.gl_pathv[i], ec)) out.emplace_back(g.gl_pathv[i]);
      }
    }
    globfree(&g);
    if (out.empty()) throw InputError(input + ": pattern matches no file");
  } else if (fs::is_directory(input, ec)) {
    for (const auto& e : fs::directory_iterator(input, ec)) {
      if (e.is_regular_file() && is_frame(e.path())) out.push_back(e.path());
    }
    if (out.empty()) throw InputError(input + ": directory has no frames (*.ply, *.png)");
  } else if (fs::is_regular_file(input, ec)) {
    out.emplace_back(input);
  } else if (fs::exists(input, ec)) {
    throw InputError(input + ": not a regular file or directory (a device, pipe or socket)");
  } else {
    throw InputError(input + ": no such file or directory");
  }
  std::sort(out.begin(), out.end(), [](const fs::path& a, const fs::path& b) {
    return natural_less(a.string(), b.string());
  });
  for (const auto& p : out) {
    if (!is_frame(p))
      throw InputError(p.string() + ": unsupported frame type (expected .ply or .png)");
  }
  return out;
}

fs::path find_intrinsics(const fs::path& frame, const std::optional<fs::path>& explicit_path) {
  if (explicit_path) return *explicit_path;
  std::error_code ec;
  const fs::path dir = frame.has_parent_path() ? frame.parent_path() : fs::path(".");
  for (const fs::path& c : {dir / "intrinsics.json", dir.parent_path() / "intrinsics.json"}) {
    if (!c.empty() && fs::is_regular_file(c, ec)) return c;
  }
  throw InputError(
      frame.string() +
      ": depth PNG needs --intrinsics (no intrinsics.json beside it or in its parent)");
}

Cloud load_frame(const fs::path& frame, const Intrinsics* intrinsics,
                 const DepthToCloudOptions& options, DepthImage* image) {
  if (image != nullptr) *image = DepthImage{};
  const std::string e = lower_ext(frame);
  if (e == ".ply") return read_ply(frame);
  if (e != ".png")
    throw InputError(frame.string() + ": unsupported frame type (expected .ply or .png)");
  if (intrinsics == nullptr) throw InputError(frame.string() + ": depth PNG needs intrinsics");
  // The size from the header first: a header may claim anything (issue 19, F4).
  const PngSize size = png_size(frame);
  if (size.bit_depth != 16)
    throw InputError(frame.string() + ": depth PNG must be 16-bit, this one is " +
                     std::to_string(size.bit_depth) + "-bit");
  if (size.width != intrinsics->width || size.height != intrinsics->height)
    throw InputError(frame.string() + ": image is " + std::to_string(size.width) + "x" +
                     std::to_string(size.height) + " but intrinsics say " +
                     std::to_string(intrinsics->width) + "x" +
                     std::to_string(intrinsics->height));
  DepthImage img = read_depth_png(frame);
  try {
    Cloud cloud = depth_to_cloud(img, *intrinsics, options);
    if (image != nullptr) *image = std::move(img);
    return cloud;
  } catch (const std::invalid_argument& ex) {
    throw InputError(frame.string() + ": " + ex.what());
  }
}

}  // namespace linksight::io
