#include "linksight/sim/recording.hpp"

#include <unistd.h>

#include <cstdio>
#include <cmath>
#include <iomanip>
#include <set>
#include <type_traits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "linksight/io/atomic_file.hpp"
#include "linksight/io/base_pose.hpp"
#include "linksight/io/chain_json.hpp"
#include "linksight/io/depth_png.hpp"
#include "linksight/io/error.hpp"
#include "linksight/io/intrinsics.hpp"
#include "linksight/io/json_input.hpp"
#include "linksight/io/ply.hpp"

// A private copy of stb (static functions): tracker_io has its own.
#define STB_IMAGE_STATIC
#define STB_IMAGE_IMPLEMENTATION
#define STBI_ONLY_PNG
#define STBI_NO_STDIO
#define STBI_FAILURE_USERMSG
#define STB_IMAGE_WRITE_STATIC
#define STB_IMAGE_WRITE_IMPLEMENTATION
#define STBI_WRITE_NO_STDIO
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#pragma GCC diagnostic ignored "-Wsign-compare"
#pragma GCC diagnostic ignored "-Wshadow"
#pragma GCC diagnostic ignored "-Wpedantic"
#pragma GCC diagnostic ignored "-Wunused-parameter"
#include <stb/stb_image.h>
#include <stb/stb_image_write.h>
#pragma GCC diagnostic pop

namespace linksight::sim {
namespace fs = std::filesystem;

void write_truth_header(std::ostream& out) {
  out << "frame,t_s,node,x_m,y_m,z_m\n" << std::fixed << std::setprecision(6);
}

void write_truth_rows(std::ostream& out, int frame, const Truth& truth,
                      const Eigen::Isometry3d& X_FW) {
  for (std::size_t j = 0; j < truth.nodes_W.size(); ++j) {
    const Eigen::Vector3d p = X_FW * truth.nodes_W[j];
    out << frame << ',' << truth.t << ',' << j << ',' << p.x() << ',' << p.y() << ',' << p.z()
        << '\n';
  }
}

void write_label_png(const fs::path& path, int width, int height,
                     const std::vector<std::uint8_t>& labels) {
  if (width <= 0 || height <= 0 || labels.size() != static_cast<std::size_t>(width) * height)
    throw io::InputError(path.string() + ": label image size does not match its data");
  std::string png;
  const int ok = stbi_write_png_to_func(
      [](void* ctx, void* data, int size) {
        static_cast<std::string*>(ctx)->append(static_cast<const char*>(data),
                                               static_cast<std::size_t>(size));
      },
      &png, width, height, 1, labels.data(), width);
  if (!ok) throw io::InputError(path.string() + ": cannot encode PNG");
  io::write_file_atomic(path, [&](std::ostream& out) { out << png; }, true);
}

std::vector<std::uint8_t> read_label_png(const fs::path& path, int& width, int& height) {
  const std::vector<char> bytes = io::read_png_checked(path);
  int channels = 0;
  if (!stbi_info_from_memory(reinterpret_cast<const unsigned char*>(bytes.data()),
                             static_cast<int>(bytes.size()), &width, &height, &channels) ||
      channels != 1 ||
      stbi_is_16_bit_from_memory(reinterpret_cast<const unsigned char*>(bytes.data()),
                                 static_cast<int>(bytes.size()))) {
    throw io::InputError(path.string() + ": not an 8-bit single-channel PNG");
  }
  unsigned char* data =
      stbi_load_from_memory(reinterpret_cast<const unsigned char*>(bytes.data()),
                            static_cast<int>(bytes.size()), &width, &height, &channels, 1);
  if (!data) throw io::InputError(path.string() + ": " + stbi_failure_reason());
  std::vector<std::uint8_t> out(data, data + static_cast<std::size_t>(width) * height);
  stbi_image_free(data);
  return out;
}

void write_camera_json(const fs::path& path, const CameraParams& camera) {
  nlohmann::json X = nlohmann::json::array();
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) X.push_back(camera.X_WC.matrix()(r, c));
  const nlohmann::json j = {{"X_WC", X},
                            {"fps", camera.fps},
                            {"z_min_m", camera.z_min},
                            {"z_max_m", camera.z_max}};
  io::write_file_atomic(path, [&](std::ostream& out) { out << j.dump(2) << '\n'; });
}

namespace {
std::string frame_name(int frame, const char* ext) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%06d.%s", frame, ext);
  return buf;
}
}  // namespace

Recorder::Recorder(fs::path dir, const CameraParams& camera, const ComponentGeometry& geometry,
                   bool force)
    : out_(std::move(dir), force), camera_(camera), geometry_(geometry) {
  std::error_code ec;
  for (const char* sub : {"depth", "labels", "clouds"}) {
    fs::create_directories(out_.path() / sub, ec);
    if (ec)
      throw io::InputError(out_.final_path().string() + ": cannot create output directory: " +
                           ec.message());
  }
  truth_.open(out_.path() / "truth.csv");
  occlusion_.open(out_.path() / "occlusion.csv");
  base_.open(out_.path() / "base_pose.csv");
  if (!truth_ || !occlusion_ || !base_) throw io::InputError(out_.final_path().string() + ": cannot write");
  write_truth_header(truth_);
  io::write_base_pose_header(base_);
  occlusion_ << "frame,component,visible_px,visible_px_unoccluded,occluded_fraction\n"
             << std::fixed << std::setprecision(6);
}

Recorder::~Recorder() = default;

void Recorder::write_frame(int frame, const Truth& truth, const DepthFrame& image,
                           const Cloud& cloud) {
  io::write_depth_png(out_.path() / "depth" / frame_name(frame, "png"), image.depth);
  write_label_png(out_.path() / "labels" / frame_name(frame, "png"), image.width, image.height,
                  image.label);
  io::write_ply(out_.path() / "clouds" / frame_name(frame, "ply"), cloud);
  write_truth_rows(truth_, frame, truth, camera_.X_WC.inverse());
  io::write_base_pose_row(base_, frame, camera_.X_WC.inverse() * truth.X_WB);
  for (std::size_t c = 0; c < image.visible_px.size(); ++c) {
    occlusion_ << frame << ',' << c << ',' << image.visible_px[c] << ','
               << image.visible_px_unoccluded[c] << ',' << image.occluded_fraction[c] << '\n';
  }
  if (!truth_ || !occlusion_ || !base_)
    throw io::InputError(out_.final_path().string() + ": write failed");
}

void Recorder::commit() {
  io::write_intrinsics(out_.path() / "intrinsics.json", camera_.intrinsics);
  write_camera_json(out_.path() / "camera.json", camera_);
  write_chain_json(out_.path() / "chain.json", geometry_);
  truth_.close();
  occlusion_.close();
  base_.close();
  if (!truth_ || !occlusion_ || !base_) throw io::InputError(out_.final_path().string() + ": write failed");
  out_.commit();
}

namespace {

// A JSON file of a recording, or an error naming it.
nlohmann::json read_json(const fs::path& path) {
  const std::string file = path.string();
  const std::string text =
      io::read_json_file(path, "cannot open (a recording from `linksight render`)");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw io::InputError(file + ": malformed JSON: " + e.what());
  }
  if (!j.is_object()) throw io::InputError(file + ": not a JSON object");
  return j;
}

struct ChainJsonIn {
  const nlohmann::json& j;
  const std::string& file;
  std::set<std::string> seen;
  template <class T>
  void operator()(const char* key, T& v, fields::Rule = {}) {
    seen.insert(key);
    const auto it = j.find(key);
    if (it == j.end()) throw io::InputError(file + ": no key '" + key + "'");
    if (!it->is_number())
      throw io::InputError(file + ": " + key + " = " + io::json_summary(*it) + ": not a number");
    const double x = it->get<double>();
    if constexpr (std::is_integral_v<T>) {
      if (!(x >= -1e9 && x <= 1e9) || x != std::floor(x))
        throw io::InputError(file + ": " + key + " = " + io::json_summary(*it) +
                             ": not a whole number");
      v = static_cast<T>(x);
    } else {
      v = x;
    }
  }
};

}  // namespace

double read_camera_fps(const fs::path& path) {
  const nlohmann::json j = read_json(path);
  const auto it = j.find("fps");
  if (it == j.end()) throw io::InputError(path.string() + ": no key 'fps'");
  if (!it->is_number() || !(it->get<double>() > 0 && it->get<double>() <= 10000))
    throw io::InputError(path.string() + ": fps = " + io::json_summary(*it) +
                         ": must be in (0, 10000]");
  return it->get<double>();
}

void write_chain_json(const fs::path& path, const ComponentGeometry& geometry) {
  io::write_file_atomic(path, [&](std::ostream& os) { os << io::chain_json(geometry, 2) << '\n'; });
}

ComponentGeometry read_chain_json(const fs::path& path) {
  const std::string file = path.string();
  const nlohmann::json j = read_json(path);
  ComponentGeometry g;
  ChainJsonIn reader{j, file, {}};
  g.fields(reader);
  for (const auto& item : j.items())
    if (!reader.seen.count(item.key()))
      throw io::InputError(file + ": unknown key '" + io::echo(item.key()) + "'");
  try {
    g.validate();
  } catch (const std::invalid_argument& e) {
    throw io::InputError(file + ": " + e.what());
  }
  return g;
}

}  // namespace linksight::sim
