#include "linksight/io/intrinsics.hpp"

#include <Eigen/LU>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <stdexcept>
#include <string>

#include "linksight/io/atomic_file.hpp"
#include "linksight/io/error.hpp"
#include "linksight/io/json_input.hpp"
#include "linksight/tracker/format.hpp"
#include "linksight/tracker/limits.hpp"

namespace linksight::io {
namespace {
// Undistorted → distorted, the Brown–Conrady model in RealSense's coefficient order.
Eigen::Vector2d brown_conrady(const Eigen::Vector2d& p, const std::array<double, 5>& c) {
  const double x = p.x(), y = p.y();
  const double r2 = x * x + y * y;
  const double f = 1 + c[0] * r2 + c[1] * r2 * r2 + c[4] * r2 * r2 * r2;
  return {x * f + 2 * c[2] * x * y + c[3] * (r2 + 2 * x * x),
          y * f + 2 * c[3] * x * y + c[2] * (r2 + 2 * y * y)};
}
// Inverts brown_conrady() by Newton's method with a numeric Jacobian: plain fixed-point
// iteration diverges for strong distortion (|1 - J| >= 1). Throws when it does not
// converge (a point outside the region where the model is invertible).
Eigen::Vector2d invert_brown_conrady(const Eigen::Vector2d& d, const std::array<double, 5>& c) {
  Eigen::Vector2d p = d;
  for (int i = 0; i < 50; ++i) {
    const Eigen::Vector2d r = brown_conrady(p, c) - d;
    if (r.norm() < 1e-14) return p;
    constexpr double h = 1e-7;
    Eigen::Matrix2d J;
    J.col(0) = (brown_conrady(p + Eigen::Vector2d(h, 0), c) -
                brown_conrady(p - Eigen::Vector2d(h, 0), c)) /
               (2 * h);
    J.col(1) = (brown_conrady(p + Eigen::Vector2d(0, h), c) -
                brown_conrady(p - Eigen::Vector2d(0, h), c)) /
               (2 * h);
    p -= J.partialPivLu().solve(r);
  }
  if ((brown_conrady(p, c) - d).norm() < 1e-10) return p;
  throw std::invalid_argument("distortion model cannot be inverted at normalized point (" +
                              std::to_string(d.x()) + ", " + std::to_string(d.y()) + ")");
}
}  // namespace

std::string_view to_string(Distortion model) {
  switch (model) {
    case Distortion::none:
      return "none";
    case Distortion::brown_conrady:
      return "brown_conrady";
    case Distortion::inverse_brown_conrady:
      return "inverse_brown_conrady";
  }
  return "unknown";
}

Distortion parse_distortion(std::string_view name) {
  for (Distortion d :
       {Distortion::none, Distortion::brown_conrady, Distortion::inverse_brown_conrady})
    if (name == to_string(d)) return d;
  throw std::invalid_argument("unknown distortion model '" + std::string(name) +
                              "' (expected none, brown_conrady or inverse_brown_conrady)");
}

namespace {
// The focal length [px] of a 1-degree field of view across the widest image a camera may
// deliver: kMaxDepthPngSide / (2 tan(0.5 degree)) = 234,678 px, rounded up.
constexpr double kMaxFocalPx = 2.35e5;
static_assert(kMaxDepthPngSide == 4096, "kMaxFocalPx follows from the widest image");
}  // namespace

void Intrinsics::validate() const {
  auto bad = [](const std::string& field, double v, const char* rule) {
    throw std::invalid_argument("intrinsics." + field + " = " + format_shortest(v) + ": " + rule);
  };
  if (width <= 0) bad("width", width, "must be > 0");
  if (height <= 0) bad("height", height, "must be > 0");
  // A longer focal length is a field of view under 1 degree across any image a camera may
  // deliver: no depth camera's (the SR300's is 71.5 x 55 degrees), and 1e308 is a typo or
  // an attack. Bounded by the widest image, not this one: a crop keeps its focal length.
  if (!(std::isfinite(fx) && fx > 0 && fx <= kMaxFocalPx))
    bad("fx", fx, "must be in (0, 235000] px (a field of view of 1 degree or more)");
  if (!(std::isfinite(fy) && fy > 0 && fy <= kMaxFocalPx))
    bad("fy", fy, "must be in (0, 235000] px (a field of view of 1 degree or more)");
  // A crop's principal point may lie outside it: finite is all.
  if (!std::isfinite(cx)) bad("cx", cx, "must be finite");
  if (!std::isfinite(cy)) bad("cy", cy, "must be finite");
  // A depth unit of a metre or more is no depth camera's (the SR300's is 1/8000 m).
  if (!(std::isfinite(depth_scale) && depth_scale > 0 && depth_scale <= 1.0))
    bad("depth_scale", depth_scale, "must be in (0, 1] m");
  for (double c : coeffs) {
    if (!std::isfinite(c)) bad("coeffs", c, "must be finite");
  }
}

Eigen::Vector3d Intrinsics::deproject(double u, double v, double z) const {
  Eigen::Vector2d n((u - cx) / fx, (v - cy) / fy);
  if (model == Distortion::inverse_brown_conrady) n = brown_conrady(n, coeffs);
  if (model == Distortion::brown_conrady) n = invert_brown_conrady(n, coeffs);
  return {n.x() * z, n.y() * z, z};
}

Eigen::Vector2d Intrinsics::project(const Eigen::Vector3d& p_C) const {
  Eigen::Vector2d n(p_C.x() / p_C.z(), p_C.y() / p_C.z());
  if (model == Distortion::brown_conrady) n = brown_conrady(n, coeffs);
  if (model == Distortion::inverse_brown_conrady) n = invert_brown_conrady(n, coeffs);
  return {n.x() * fx + cx, n.y() * fy + cy};
}

Intrinsics read_intrinsics(const std::filesystem::path& path) {
  const std::string file = path.string();
  const std::string text = read_json_file(path, "cannot open intrinsics");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {  // parse_error, and out_of_range for 1e999
    throw InputError(file + ": malformed JSON: " + e.what());
  }
  if (!j.is_object()) throw InputError(file + ": expected a JSON object");
  static const std::set<std::string> known = {"width", "height",      "fx",    "fy",    "cx",
                                              "cy",    "depth_scale", "model", "coeffs"};
  for (const auto& [key, value] : j.items()) {
    if (!known.count(key)) throw InputError(file + ": unknown key '" + echo(key) + "'");
  }
  auto number = [&](const char* key) -> double {
    if (!j.contains(key)) throw InputError(file + ": missing key '" + key + "'");
    if (!j[key].is_number()) throw InputError(file + ": key '" + key + "' must be a number");
    return j[key].get<double>();
  };
  auto integer = [&](const char* key) -> int {
    const double v = number(key);
    if (v != std::floor(v) || v < 1 || v > 1e6) {
      throw InputError(file + ": key '" + key + "' must be a positive integer");
    }
    return static_cast<int>(v);
  };
  Intrinsics k;
  k.width = integer("width");
  k.height = integer("height");
  k.fx = number("fx");
  k.fy = number("fy");
  k.cx = number("cx");
  k.cy = number("cy");
  k.depth_scale = number("depth_scale");
  if (j.contains("model")) {
    if (!j["model"].is_string()) throw InputError(file + ": key 'model' must be a string");
    try {
      k.model = parse_distortion(j["model"].get<std::string>());
    } catch (const std::invalid_argument& e) {
      throw InputError(file + ": key 'model': " + e.what());
    }
  }
  if (j.contains("coeffs")) {
    const auto& c = j["coeffs"];
    if (!c.is_array() || c.size() != 5) {
      throw InputError(file + ": key 'coeffs' must be an array of 5 numbers");
    }
    for (std::size_t i = 0; i < 5; ++i) {
      if (!c[i].is_number())
        throw InputError(file + ": key 'coeffs' must be an array of 5 numbers");
      k.coeffs[i] = c[i].get<double>();
    }
  } else if (k.model != Distortion::none) {
    throw InputError(file + ": key 'model' needs key 'coeffs'");
  }
  try {
    k.validate();
  } catch (const std::invalid_argument& e) {
    throw InputError(file + ": " + e.what());
  }
  return k;
}

std::string intrinsics_json(const Intrinsics& k, int indent) {
  nlohmann::json j = {
      {"width", k.width}, {"height", k.height},          {"fx", k.fx}, {"fy", k.fy}, {"cx", k.cx},
      {"cy", k.cy},       {"depth_scale", k.depth_scale}};
  if (k.model != Distortion::none) {
    j["model"] = to_string(k.model);
    j["coeffs"] = k.coeffs;
  }
  return j.dump(indent);
}

void write_intrinsics(const std::filesystem::path& path, const Intrinsics& k) {
  write_file_atomic(path, [&](std::ostream& out) { out << intrinsics_json(k, 2) << "\n"; });
}

}  // namespace linksight::io
