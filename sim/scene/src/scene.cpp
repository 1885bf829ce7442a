#include "linksight/sim/scene.hpp"

#include "linksight/sim/occlusion.hpp"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <numbers>
#include <set>
#include <string>

#include "linksight/io/error.hpp"
#include "linksight/tracker/seed.hpp"

namespace linksight::sim {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

// Reads typed values out of YAML nodes, rejecting unknown keys, with file:line in errors.
// A `--set key=value` override: the key path and the text given.
struct Override {
  std::string key, value;
};

class Reader {
 public:
  Reader(std::string file, std::vector<Override> overrides = {})
      : file_(std::move(file)), overrides_(std::move(overrides)) {}

  [[noreturn]] void fail(const YAML::Node& node, const std::string& key,
                         const std::string& what) const {
    // An overridden key (or one inside it) has no line in the file: name the --set.
    for (const Override& o : overrides_) {
      if (key == o.key || key.starts_with(o.key + ".") || key.starts_with(o.key + "[")) {
        throw io::InputError(file_ + ": --set " + o.key + "=" + o.value + ": " + key + ": " +
                             what);
      }
    }
    const int line = node.IsDefined() && node.Mark().line >= 0 ? node.Mark().line + 1 : 0;
    throw io::InputError(file_ + ":" + std::to_string(line) + ": " + key + ": " + what);
  }
  void only(const YAML::Node& map, const std::string& where,
            const std::set<std::string>& keys) const {
    if (!map.IsMap()) fail(map, where, "expected a mapping");
    for (const auto& kv : map) {
      const std::string k = kv.first.as<std::string>();
      if (!keys.count(k)) fail(kv.first, where.empty() ? k : where + "." + k, "unknown key");
    }
  }
  double number(const YAML::Node& map, const std::string& where, const char* key, double fallback,
                double lo, double hi) const {
    const YAML::Node n = map[key];
    if (!n) return fallback;
    const std::string name = where.empty() ? key : where + "." + key;
    double v = 0;
    try {
      v = n.as<double>();
    } catch (const YAML::Exception&) {
      fail(n, name, "expected a number");
    }
    if (!(v >= lo && v <= hi)) {
      fail(n, name,
           std::to_string(v) + " is out of range [" + std::to_string(lo) + ", " +
               std::to_string(hi) + "]");
    }
    return v;
  }
  std::string text(const YAML::Node& map, const std::string& where, const char* key,
                   const std::string& fallback) const {
    const YAML::Node n = map[key];
    if (!n) return fallback;
    if (!n.IsScalar()) fail(n, where.empty() ? key : where + "." + key, "expected a string");
    return n.as<std::string>();
  }
  // A string out of `choices`.
  std::string choice(const YAML::Node& map, const std::string& where, const char* key,
                     const std::string& fallback, const std::set<std::string>& choices) const {
    const std::string v = text(map, where, key, fallback);
    if (!choices.count(v)) {
      std::string list;
      for (const std::string& c : choices) list += (list.empty() ? "" : ", ") + c;
      fail(map[key], where + "." + key, "'" + v + "' is not one of " + list);
    }
    return v;
  }
  bool boolean(const YAML::Node& map, const std::string& where, const char* key,
               bool fallback) const {
    const YAML::Node n = map[key];
    if (!n) return fallback;
    try {
      return n.as<bool>();
    } catch (const YAML::Exception&) {
      fail(n, where + "." + key, "expected true or false");
    }
  }
  Eigen::Vector3d vec3(const YAML::Node& map, const std::string& where, const char* key,
                       const Eigen::Vector3d& fallback) const {
    const YAML::Node n = map[key];
    if (!n) return fallback;
    const std::string name = where + "." + key;
    if (!n.IsSequence() || n.size() != 3) fail(n, name, "expected [x, y, z]");
    Eigen::Vector3d v;
    for (int i = 0; i < 3; ++i) {
      try {
        v[i] = n[i].as<double>();
      } catch (const YAML::Exception&) {
        fail(n, name, "expected three numbers");
      }
    }
    if (!v.allFinite()) fail(n, name, "must be finite");
    return v;
  }
  // A pose: position_m [x, y, z] and rpy_deg [roll, pitch, yaw] (fixed axes x, y, z).
  Eigen::Isometry3d pose(const YAML::Node& map, const std::string& where) const {
    Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
    X.translation() = vec3(map, where, "position_m", Eigen::Vector3d::Zero());
    const Eigen::Vector3d rpy = vec3(map, where, "rpy_deg", Eigen::Vector3d::Zero()) * kDeg;
    X.linear() = (Eigen::AngleAxisd(rpy.z(), Eigen::Vector3d::UnitZ()) *
                  Eigen::AngleAxisd(rpy.y(), Eigen::Vector3d::UnitY()) *
                  Eigen::AngleAxisd(rpy.x(), Eigen::Vector3d::UnitX()))
                     .toRotationMatrix();
    return X;
  }
  BaseTrajectory trajectory(const YAML::Node& map, const std::string& where) const {
    only(map, where, {"waypoints", "sweeps"});
    std::vector<Waypoint> wps;
    if (const YAML::Node w = map["waypoints"]) {
      if (!w.IsSequence()) fail(w, where + ".waypoints", "expected a list");
      for (std::size_t i = 0; i < w.size(); ++i) {
        const std::string at = where + ".waypoints[" + std::to_string(i) + "]";
        only(w[i], at, {"t_s", "position_m", "rpy_deg"});
        wps.push_back({number(w[i], at, "t_s", 0.0, 0.0, 1e6), pose(w[i], at)});
      }
    }
    std::vector<Sweep> sweeps;
    if (const YAML::Node s = map["sweeps"]) {
      if (!s.IsSequence()) fail(s, where + ".sweeps", "expected a list");
      for (std::size_t i = 0; i < s.size(); ++i) {
        const std::string at = where + ".sweeps[" + std::to_string(i) + "]";
        only(s[i], at, {"axis", "amplitude_deg", "offset_m", "frequency_hz", "phase_deg"});
        Sweep sw;
        sw.axis_B = vec3(s[i], at, "axis", sw.axis_B);
        if (sw.axis_B.norm() < 1e-9) fail(s[i]["axis"], at + ".axis", "must not be zero");
        sw.amplitude = number(s[i], at, "amplitude_deg", 0.0, -180, 180) * kDeg;
        sw.offset_W = vec3(s[i], at, "offset_m", sw.offset_W);
        sw.frequency = number(s[i], at, "frequency_hz", sw.frequency, 0.0, 100.0);
        sw.phase = number(s[i], at, "phase_deg", 0.0, -360, 360) * kDeg;
        sweeps.push_back(sw);
      }
    }
    try {
      return BaseTrajectory(std::move(wps), std::move(sweeps));
    } catch (const std::invalid_argument& e) {
      fail(map, where, e.what());
    }
  }

  // shape: box | cylinder | sphere | mesh, with its sizes. `base` resolves mesh paths.
  Shape shape(const YAML::Node& map, const std::string& where,
              const std::filesystem::path& base) const {
    Shape sh;
    const std::string kind =
        choice(map, where, "shape", "box", {"box", "cylinder", "sphere", "mesh"});
    sh.kind = kind == "box"        ? Shape::Kind::box
              : kind == "cylinder" ? Shape::Kind::cylinder
              : kind == "sphere"   ? Shape::Kind::sphere
                                   : Shape::Kind::mesh;
    sh.half_extents = vec3(map, where, "half_extents_m", sh.half_extents);
    if (!(sh.half_extents.minCoeff() > 0))
      fail(map["half_extents_m"], where + ".half_extents_m", "must all be > 0");
    sh.radius = number(map, where, "radius_m", sh.radius, 1e-4, 10.0);
    sh.half_length = number(map, where, "half_length_m", sh.half_length, 1e-4, 10.0);
    sh.scale = number(map, where, "scale", sh.scale, 1e-6, 1e6);
    if (sh.kind == Shape::Kind::mesh) {
      if (!map["mesh"]) fail(map, where + ".mesh", "a mesh shape needs a mesh file");
      const std::filesystem::path file = text(map, where, "mesh", "");
      sh.mesh = file.is_absolute() ? file : base / file;
      std::error_code ec;
      if (!std::filesystem::is_regular_file(sh.mesh, ec))
        fail(map["mesh"], where + ".mesh", sh.mesh.string() + ": mesh file not found");
    } else if (map["mesh"]) {
      fail(map["mesh"], where + ".mesh", "only for shape: mesh");
    }
    return sh;
  }

 private:
  std::string file_;
  std::vector<Override> overrides_;
};

// Applies "a.b[0].c=value" to the tree; intermediate mappings are created, list elements
// must exist. The value is parsed as YAML.
Override apply_override(const std::string& file, YAML::Node& root, const std::string& text) {
  const auto eq = text.find('=');
  if (eq == std::string::npos || eq == 0)
    throw io::InputError(file + ": --set " + text + ": expected key.path=value");
  Override o{text.substr(0, eq), text.substr(eq + 1)};
  auto bad = [&](const std::string& what) {
    throw io::InputError(file + ": --set " + text + ": " + what);
  };
  YAML::Node value;
  try {
    value = YAML::Load(o.value);
  } catch (const YAML::Exception& e) {
    bad("value is not valid YAML: " + e.msg);
  }
  if (!value.IsDefined() || value.IsNull()) bad("no value");
  // Split into steps: a key name or a list index.
  struct Step {
    std::string key;
    int index = -1;
  };
  std::vector<Step> steps;
  std::size_t i = 0;
  const std::string& k = o.key;
  while (i < k.size()) {
    if (k[i] == '.') {
      if (i == 0 || i + 1 == k.size() || k[i + 1] == '.') bad("empty key in '" + k + "'");
      ++i;
    } else if (k[i] == '[') {
      const auto close = k.find(']', i);
      if (close == std::string::npos || steps.empty()) bad("bad index in '" + k + "'");
      const std::string digits = k.substr(i + 1, close - i - 1);
      if (digits.empty() || digits.find_first_not_of("0123456789") != std::string::npos ||
          digits.size() > 6)
        bad("bad index '" + digits + "'");
      steps.push_back({"", std::stoi(digits)});
      i = close + 1;
    } else {
      const auto end = k.find_first_of(".[", i);
      steps.push_back({k.substr(i, end == std::string::npos ? std::string::npos : end - i)});
      i = end == std::string::npos ? k.size() : end;
    }
  }
  if (steps.empty() || steps.front().index >= 0) bad("no key");
  YAML::Node node;
  node.reset(root);
  for (std::size_t s = 0; s < steps.size(); ++s) {
    const bool last = s + 1 == steps.size();
    if (steps[s].index >= 0) {
      if (!node.IsSequence() || static_cast<int>(node.size()) <= steps[s].index)
        bad("the scene has no element " + std::to_string(steps[s].index) + " there");
      if (last) {
        node[steps[s].index] = value;
      } else {
        YAML::Node next = node[steps[s].index];
        node.reset(next);
      }
      continue;
    }
    if (!node.IsMap() && !node.IsNull()) bad("'" + steps[s].key + "' is inside a non-mapping");
    if (last) {
      node[steps[s].key] = value;
    } else {
      if (!node[steps[s].key]) node[steps[s].key] = YAML::Node(YAML::NodeType::Map);
      YAML::Node next = node[steps[s].key];
      node.reset(next);
    }
  }
  return o;
}

const std::set<std::string> kShapeKeys = {"shape",  "half_extents_m", "radius_m", "half_length_m",
                                          "mesh",   "scale",          "reflectance"};

std::set<std::string> with(std::set<std::string> keys, std::initializer_list<const char*> more) {
  for (const char* k : more) keys.insert(k);
  return keys;
}

void read_camera(const Reader& r, const YAML::Node& c, CameraParams& cam) {
  r.only(c, "camera",
         {"preset", "fps", "width", "height", "fx", "fy", "cx", "cy", "depth_scale_m",
          "distortion", "coeffs", "z_min_m", "z_max_m", "look_at", "X_WC"});
  (void)r.choice(c, "camera", "preset", "sr300", {"sr300"});
  io::Intrinsics& k = cam.intrinsics;
  cam.fps = r.number(c, "camera", "fps", cam.fps, 1.0, 1000.0);
  k.width = static_cast<int>(r.number(c, "camera", "width", k.width, 1, 8192));
  k.height = static_cast<int>(r.number(c, "camera", "height", k.height, 1, 8192));
  k.fx = r.number(c, "camera", "fx", k.fx, 1e-3, 1e5);
  k.fy = r.number(c, "camera", "fy", k.fy, 1e-3, 1e5);
  k.cx = r.number(c, "camera", "cx", k.cx, -1e5, 1e5);
  k.cy = r.number(c, "camera", "cy", k.cy, -1e5, 1e5);
  k.depth_scale = r.number(c, "camera", "depth_scale_m", k.depth_scale, 1e-7, 1.0);
  const std::string model = r.choice(c, "camera", "distortion", "none",
                                     {"none", "brown_conrady", "inverse_brown_conrady"});
  k.model = model == "none"            ? io::Distortion::none
            : model == "brown_conrady" ? io::Distortion::brown_conrady
                                       : io::Distortion::inverse_brown_conrady;
  if (const YAML::Node co = c["coeffs"]) {
    if (!co.IsSequence() || co.size() != 5) r.fail(co, "camera.coeffs", "expected 5 numbers");
    for (std::size_t i = 0; i < 5; ++i) {
      try {
        k.coeffs[i] = co[i].as<double>();
      } catch (const YAML::Exception&) {
        r.fail(co, "camera.coeffs", "expected 5 numbers");
      }
    }
  }
  cam.z_min = r.number(c, "camera", "z_min_m", cam.z_min, 0.0, 100.0);
  cam.z_max = r.number(c, "camera", "z_max_m", cam.z_max, 0.0, 100.0);
  if (!(cam.z_max > cam.z_min)) r.fail(c["z_max_m"] ? c["z_max_m"] : c, "camera.z_max_m",
                                      "must be greater than z_min_m");
  if (c["look_at"] && c["X_WC"]) r.fail(c["X_WC"], "camera.X_WC", "give look_at or X_WC, not both");
  if (const YAML::Node l = c["look_at"]) {
    r.only(l, "camera.look_at", {"eye_m", "target_m", "up"});
    try {
      cam.X_WC = look_at(r.vec3(l, "camera.look_at", "eye_m", {0.25, -0.6, 0.6}),
                         r.vec3(l, "camera.look_at", "target_m", {0.25, 0.0, 0.45}),
                         r.vec3(l, "camera.look_at", "up", Eigen::Vector3d::UnitZ()));
    } catch (const std::invalid_argument& e) {
      r.fail(l, "camera.look_at", e.what());
    }
  }
  if (const YAML::Node m = c["X_WC"]) {
    if (!m.IsSequence() || m.size() != 16)
      r.fail(m, "camera.X_WC", "expected 16 numbers (4x4, row-major)");
    Eigen::Matrix4d M;
    for (int i = 0; i < 16; ++i) {
      try {
        M(i / 4, i % 4) = m[i].as<double>();
      } catch (const YAML::Exception&) {
        r.fail(m, "camera.X_WC", "expected 16 numbers");
      }
    }
    if (!M.row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1)))
      r.fail(m, "camera.X_WC", "last row must be 0 0 0 1");
    cam.X_WC.matrix() = M;
  }
  try {
    cam.validate();
  } catch (const std::invalid_argument& e) {
    r.fail(c, "camera", e.what());
  }
}

void read_noise(const Reader& r, const YAML::Node& n, NoiseParams& noise) {
  r.only(n, "noise",
         {"preset", "scale", "axial", "lateral", "shadow", "dropouts", "edges", "quantize"});
  noise = NoiseParams::preset(r.choice(n, "noise", "preset", "sr300", {"off", "sr300"}));
  constexpr double deg = std::numbers::pi / 180.0;
  if (const YAML::Node a = n["axial"]) {
    r.only(a, "noise.axial",
           {"enabled", "a_m", "c_per_m", "k_theta", "theta_cap_deg", "correlation_px"});
    AxialNoise& x = noise.axial;
    x.enabled = r.boolean(a, "noise.axial", "enabled", true);
    x.a = r.number(a, "noise.axial", "a_m", x.a, 0.0, 0.1);
    x.c = r.number(a, "noise.axial", "c_per_m", x.c, 0.0, 0.1);
    x.k_theta = r.number(a, "noise.axial", "k_theta", x.k_theta, 0.0, 0.1);
    x.theta_cap = r.number(a, "noise.axial", "theta_cap_deg", x.theta_cap / deg, 0.0, 89.9) * deg;
    x.correlation_px = r.number(a, "noise.axial", "correlation_px", x.correlation_px, 0.0, 10.0);
  }
  if (const YAML::Node l = n["lateral"]) {
    r.only(l, "noise.lateral", {"enabled", "sigma_px"});
    noise.lateral.enabled = r.boolean(l, "noise.lateral", "enabled", true);
    noise.lateral.sigma_px = r.number(l, "noise.lateral", "sigma_px", noise.lateral.sigma_px, 0, 10);
  }
  if (const YAML::Node s = n["shadow"]) {
    r.only(s, "noise.shadow", {"enabled", "baseline_m"});
    noise.shadow.enabled = r.boolean(s, "noise.shadow", "enabled", true);
    noise.shadow.baseline =
        r.number(s, "noise.shadow", "baseline_m", noise.shadow.baseline, -1.0, 1.0);
  }
  if (const YAML::Node d = n["dropouts"]) {
    r.only(d, "noise.dropouts",
           {"enabled", "max_incidence_deg", "min_signal", "hole_rate", "hole_median_px",
            "hole_p90_px"});
    Dropouts& x = noise.dropouts;
    x.enabled = r.boolean(d, "noise.dropouts", "enabled", true);
    x.max_incidence =
        r.number(d, "noise.dropouts", "max_incidence_deg", x.max_incidence / deg, 0.1, 90) * deg;
    x.min_signal = r.number(d, "noise.dropouts", "min_signal", x.min_signal, 0.0, 1e6);
    x.hole_rate = r.number(d, "noise.dropouts", "hole_rate", x.hole_rate, 0.0, 1e4);
    x.hole_median_px =
        r.number(d, "noise.dropouts", "hole_median_px", x.hole_median_px, 1, Dropouts::kMaxHolePx);
    x.hole_p90_px = r.number(d, "noise.dropouts", "hole_p90_px", x.hole_p90_px, x.hole_median_px,
                             Dropouts::kMaxHolePx);
  }
  if (const YAML::Node e = n["edges"]) {
    r.only(e, "noise.edges", {"enabled", "jump_m", "band_p1", "band_p2", "p_drop", "p_flying",
                              "flying_position", "flying_spread"});
    EdgeEffects& x = noise.edges;
    x.enabled = r.boolean(e, "noise.edges", "enabled", true);
    x.jump = r.number(e, "noise.edges", "jump_m", x.jump, 1e-6, 10);
    x.p_drop = r.number(e, "noise.edges", "p_drop", x.p_drop, 0, 1);
    x.p_flying = r.number(e, "noise.edges", "p_flying", x.p_flying, 0, 1);
    x.band_p1 = r.number(e, "noise.edges", "band_p1", x.band_p1, 0, 1);
    x.band_p2 = r.number(e, "noise.edges", "band_p2", x.band_p2, 0, 1);
    x.flying_position = r.number(e, "noise.edges", "flying_position", x.flying_position, 0, 1);
    x.flying_spread = r.number(e, "noise.edges", "flying_spread", x.flying_spread, 0, 1);
  }
  noise.quantize = r.boolean(n, "noise", "quantize", noise.quantize);
  // One knob for sweeps: scales every random term (axial sigma, ray jitter) after the
  // blocks above; dropouts, edges and shadows are left as they are.
  const double scale = r.number(n, "noise", "scale", 1.0, 0.0, 100.0);
  noise.axial.a *= scale;
  noise.axial.c *= scale;
  noise.axial.k_theta *= scale;
  noise.lateral.sigma_px *= scale;
}

void read_segmentation(const Reader& r, const YAML::Node& n, ExtractParams& p) {
  const char* w = "segmentation";
  r.only(n, w,
         {"mode", "leakage", "leakage_px", "min_depth_m", "max_depth_m", "crop_min_m",
          "crop_max_m", "max_planes", "plane_threshold_m", "min_plane_fraction",
          "ransac_iterations"});
  p.mode = ExtractParams::mode_from(r.choice(n, w, "mode", "truth", {"truth", "depth"}));
  p.leakage = r.number(n, w, "leakage", p.leakage, 0, 1);
  p.leakage_px = static_cast<int>(r.number(n, w, "leakage_px", p.leakage_px, 0, 50));
  p.min_depth = r.number(n, w, "min_depth_m", p.min_depth, 0, 100);
  p.max_depth = r.number(n, w, "max_depth_m", p.max_depth, 0, 100);
  if (!(p.max_depth > p.min_depth)) r.fail(n, "segmentation.max_depth_m", "must exceed min_depth_m");
  if (n["crop_min_m"] || n["crop_max_m"]) {
    if (!n["crop_min_m"] || !n["crop_max_m"])
      r.fail(n, "segmentation.crop_min_m", "give crop_min_m and crop_max_m together");
    p.crop_C = Eigen::AlignedBox3d(r.vec3(n, w, "crop_min_m", Eigen::Vector3d::Zero()),
                                   r.vec3(n, w, "crop_max_m", Eigen::Vector3d::Zero()));
    if (p.crop_C->isEmpty()) r.fail(n["crop_max_m"], "segmentation.crop_max_m", "box is empty");
  }
  p.max_planes = static_cast<int>(r.number(n, w, "max_planes", p.max_planes, 0, 10));
  p.plane_threshold = r.number(n, w, "plane_threshold_m", p.plane_threshold, 1e-5, 1);
  p.min_plane_fraction = r.number(n, w, "min_plane_fraction", p.min_plane_fraction, 1e-3, 1);
  p.ransac_iterations =
      static_cast<int>(r.number(n, w, "ransac_iterations", p.ransac_iterations, 1, 100000));
}

void read_background(const Reader& r, const YAML::Node& b, const std::filesystem::path& base,
                     std::vector<BackgroundObject>& out) {
  r.only(b, "background", {"table", "wall", "objects"});
  if (const YAML::Node t = b["table"]) {
    r.only(t, "background.table", {"height_m", "center_m", "half_size_m", "reflectance"});
    BackgroundObject o;
    const double h = r.number(t, "background.table", "height_m", 0.3, -10, 10);
    const Eigen::Vector3d c = r.vec3(t, "background.table", "center_m", {0.25, 0.0, 0.0});
    const Eigen::Vector3d hs = r.vec3(t, "background.table", "half_size_m", {0.6, 0.6, 0.01});
    if (!(hs.minCoeff() > 0)) r.fail(t["half_size_m"], "background.table.half_size_m", "must all be > 0");
    o.shape.half_extents = hs;
    o.X_WO.translation() = Eigen::Vector3d(c.x(), c.y(), h - hs.z());  // top face at height_m
    o.reflectance = r.number(t, "background.table", "reflectance", 1.0, 0, 10);
    out.push_back(o);
  }
  if (const YAML::Node wl = b["wall"]) {
    r.only(wl, "background.wall", {"position_m", "rpy_deg", "half_extents_m", "reflectance"});
    BackgroundObject o;
    o.shape.half_extents = r.vec3(wl, "background.wall", "half_extents_m", {1.0, 0.01, 1.0});
    if (!(o.shape.half_extents.minCoeff() > 0))
      r.fail(wl["half_extents_m"], "background.wall.half_extents_m", "must all be > 0");
    o.X_WO = r.pose(wl, "background.wall");
    o.reflectance = r.number(wl, "background.wall", "reflectance", 1.0, 0, 10);
    out.push_back(o);
  }
  if (const YAML::Node objs = b["objects"]) {
    if (!objs.IsSequence()) r.fail(objs, "background.objects", "expected a list");
    for (std::size_t i = 0; i < objs.size(); ++i) {
      const std::string at = "background.objects[" + std::to_string(i) + "]";
      r.only(objs[i], at, with(kShapeKeys, {"position_m", "rpy_deg"}));
      BackgroundObject o;
      o.shape = r.shape(objs[i], at, base);
      o.X_WO = r.pose(objs[i], at);
      o.reflectance = r.number(objs[i], at, "reflectance", 1.0, 0, 10);
      out.push_back(o);
    }
  }
}

void read_tracker(const Reader& r, const YAML::Node& n, TrackerParams& p) {
  const char* w = "tracker";
  r.only(n, w,
         {"mode", "init", "som_init", "backend", "threads", "iterations", "poly_order",
          "max_points", "tolerance_m"});
  const std::vector<std::string> modes = mode_names();
  p.mode = parse_mode(r.choice(n, w, "mode", std::string(to_string(p.mode)),
                               std::set<std::string>(modes.begin(), modes.end())));
  InitParams& lsq = p.policy.lsq_init;
  lsq.method = parse_init(r.choice(n, w, "init", lsq.method == InitMethod::pca ? "pca" : "paper",
                                   {"paper", "pca"}));
  p.policy.som_init.method = parse_som_init(
      r.choice(n, w, "som_init", std::string(to_string(p.policy.som_init.method)),
               {std::string(to_string(SomInit::straight_line)),
                std::string(to_string(SomInit::random_sample))}));
  p.backend = parse_backend(r.choice(n, w, "backend", std::string(to_string(p.backend)),
                                     {"serial", "openmp", "opencl"}));
  p.threads = static_cast<int>(r.number(n, w, "threads", p.threads, 0, kMaxThreads));
  p.iterations = static_cast<int>(r.number(n, w, "iterations", p.iterations, 1, kMaxIterations));
  lsq.poly_order = static_cast<int>(r.number(n, w, "poly_order", lsq.poly_order, 1, 9));
  lsq.max_points =
      static_cast<std::size_t>(r.number(n, w, "max_points", static_cast<double>(lsq.max_points), 0, 1e7));
  p.tolerance = r.number(n, w, "tolerance_m", p.tolerance, 0, 1);
}

}  // namespace

Scene load_scene(const std::filesystem::path& path, const std::vector<std::string>& overrides) {
  const std::string file = path.string();
  YAML::Node root;
  try {
    root = YAML::LoadFile(file);
  } catch (const YAML::BadFile&) {
    throw io::InputError(file + ": cannot open scene");
  } catch (const YAML::ParserException& e) {
    throw io::InputError(file + ":" + std::to_string(e.mark.line + 1) +
                         ": malformed YAML: " + e.msg);
  }
  if (!root.IsMap()) Reader(file).fail(root, "(top level)", "expected a mapping");
  std::vector<Override> applied;
  for (const std::string& o : overrides) applied.push_back(apply_override(file, root, o));
  const Reader r(file, applied);
  r.only(root, "", {"duration_s", "seed", "camera", "noise", "occluders", "occlusion", "background",
                    "segmentation", "chain", "world", "base", "actions", "tracker"});
  const std::filesystem::path base = path.parent_path();
  Scene s;
  s.duration_s = r.number(root, "", "duration_s", s.duration_s, 1e-3, 3600.0);
  s.seed = static_cast<std::uint64_t>(r.number(root, "", "seed", 1.0, 0.0, 9007199254740992.0));
  if (const YAML::Node c = root["camera"]) read_camera(r, c, s.camera);
  if (const YAML::Node n = root["noise"]) read_noise(r, n, s.noise);
  if (const YAML::Node n = root["segmentation"]) read_segmentation(r, n, s.segmentation);
  if (const YAML::Node b = root["background"]) read_background(r, b, base, s.background);
  if (const YAML::Node o = root["occluders"]) {
    if (!o.IsSequence()) r.fail(o, "occluders", "expected a list");
    if (o.size() > static_cast<std::size_t>(kMaxOccluders))
      r.fail(o, "occluders", "at most " + std::to_string(kMaxOccluders));
    for (std::size_t i = 0; i < o.size(); ++i) {
      const std::string at = "occluders[" + std::to_string(i) + "]";
      r.only(o[i], at, with(kShapeKeys, {"path", "from_s", "to_s"}));
      Occluder oc;
      oc.shape = r.shape(o[i], at, base);
      oc.reflectance = r.number(o[i], at, "reflectance", 1.0, 0, 10);
      if (const YAML::Node route = o[i]["path"]) oc.path = r.trajectory(route, at + ".path");
      oc.from_s = r.number(o[i], at, "from_s", 0.0, 0.0, 1e6);
      if (o[i]["to_s"]) {
        oc.to_s = r.number(o[i], at, "to_s", 0.0, 0.0, 1e6);
        if (!(oc.to_s > oc.from_s))
          r.fail(o[i]["to_s"], at + ".to_s",
                 std::to_string(oc.to_s) + " must be > from_s (" + std::to_string(oc.from_s) + ")");
      }
      if (!o[i]["from_s"]) oc.from_s = -std::numeric_limits<double>::infinity();
      s.occluders.push_back(oc);
    }
  }
  if (const YAML::Node c = root["chain"]) {
    r.only(c, "chain",
           {"ball_radius_m", "pitch_m", "neck_radius_m", "neck_length_m", "count",
            "component_mass_kg", "preload_n", "friction", "cone_limit_deg"});
    ComponentGeometry& g = s.chain.geometry;
    g.ball_radius = r.number(c, "chain", "ball_radius_m", g.ball_radius, 1e-4, 1.0);
    g.pitch = r.number(c, "chain", "pitch_m", g.pitch, 1e-4, 1.0);
    g.neck_radius = r.number(c, "chain", "neck_radius_m", g.neck_radius, 1e-4, 1.0);
    g.neck_length = r.number(c, "chain", "neck_length_m", g.neck_length, 0.0, 1.0);
    g.count = static_cast<int>(r.number(c, "chain", "count", g.count, 1, 100));
    s.chain.component_mass =
        r.number(c, "chain", "component_mass_kg", s.chain.component_mass, 1e-6, 100);
    s.chain.preload_force = r.number(c, "chain", "preload_n", s.chain.preload_force, 0.0, 1e6);
    s.chain.friction_coefficient =
        r.number(c, "chain", "friction", s.chain.friction_coefficient, 0.0, 10.0);
    s.chain.cone_limit =
        r.number(c, "chain", "cone_limit_deg", s.chain.cone_limit / kDeg, 0.1, 89.9) * kDeg;
  }
  if (const YAML::Node w = root["world"]) {
    r.only(w, "world", {"dt_s", "gravity", "g"});
    s.world.dt = r.number(w, "world", "dt_s", s.world.dt, 1e-5, 0.01);
    s.world.gravity = r.boolean(w, "world", "gravity", s.world.gravity);
    s.world.g = r.number(w, "world", "g", s.world.g, 0.0, 100.0);
  }
  if (const YAML::Node b = root["base"]) s.base = r.trajectory(b, "base");
  if (const YAML::Node a = root["actions"]) {
    r.only(a, "actions", {"forces", "gravity", "pushers", "obstacles"});
    if (const YAML::Node gv = a["gravity"]) {
      if (!gv.IsSequence()) r.fail(gv, "actions.gravity", "expected a list");
      for (std::size_t i = 0; i < gv.size(); ++i) {
        const std::string at = "actions.gravity[" + std::to_string(i) + "]";
        r.only(gv[i], at, {"t_s", "on"});
        s.gravity_switches.push_back(
            {r.number(gv[i], at, "t_s", 0.0, 0.0, 1e6), r.boolean(gv[i], at, "on", true)});
      }
    }
    if (const YAML::Node f = a["forces"]) {
      for (std::size_t i = 0; i < f.size(); ++i) {
        const std::string at = "actions.forces[" + std::to_string(i) + "]";
        r.only(f[i], at, {"component", "force_n", "torque_nm", "t_start_s", "t_end_s"});
        ForceAction fa;
        fa.component =
            static_cast<int>(r.number(f[i], at, "component", 0, 0, s.chain.geometry.count - 1));
        fa.force_W = r.vec3(f[i], at, "force_n", fa.force_W);
        fa.torque_W = r.vec3(f[i], at, "torque_nm", fa.torque_W);
        fa.t_start = r.number(f[i], at, "t_start_s", 0.0, 0.0, 1e6);
        fa.t_end = r.number(f[i], at, "t_end_s", fa.t_start, fa.t_start, 1e6);
        s.forces.push_back(fa);
      }
    }
    if (const YAML::Node p = a["pushers"]) {
      for (std::size_t i = 0; i < p.size(); ++i) {
        const std::string at = "actions.pushers[" + std::to_string(i) + "]";
        r.only(p[i], at, {"radius_m", "length_m", "path"});
        PusherParams pp;
        pp.radius = r.number(p[i], at, "radius_m", pp.radius, 1e-4, 1.0);
        pp.length = r.number(p[i], at, "length_m", pp.length, 0.0, 2.0);
        if (const YAML::Node route = p[i]["path"]) pp.path = r.trajectory(route, at + ".path");
        s.pushers.push_back(pp);
      }
    }
    if (const YAML::Node o = a["obstacles"]) {
      for (std::size_t i = 0; i < o.size(); ++i) {
        const std::string at = "actions.obstacles[" + std::to_string(i) + "]";
        r.only(o[i], at, {"half_extents_m", "position_m", "rpy_deg"});
        ObstacleParams op;
        op.half_extents = r.vec3(o[i], at, "half_extents_m", op.half_extents);
        if (!(op.half_extents.minCoeff() > 0))
          r.fail(o[i]["half_extents_m"], at + ".half_extents_m", "must all be > 0");
        op.X_WO = r.pose(o[i], at);
        s.obstacles.push_back(op);
      }
    }
  }
  if (const YAML::Node o = root["occlusion"]) {
    r.only(o, "occlusion", {"fraction", "at", "from_s", "to_s", "gap_m", "height_m", "follow_base"});
    ScreenOcclusion& so = s.occlusion;
    so.fraction = r.number(o, "occlusion", "fraction", so.fraction, 0.0, 0.95);
    so.at = r.choice(o, "occlusion", "at", "middle", {"middle", "tip"}) == "tip"
                ? ScreenOcclusion::Where::tip
                : ScreenOcclusion::Where::middle;
    so.from_s = r.number(o, "occlusion", "from_s", so.from_s, 0.0, 1e6);
    so.to_s = r.number(o, "occlusion", "to_s", so.to_s, 0.0, 1e6);
    if (!(so.to_s > so.from_s))
      r.fail(o["to_s"] ? o["to_s"] : o, "occlusion.to_s",
             std::to_string(so.to_s) + " must be > from_s (" + std::to_string(so.from_s) + ")");
    so.gap = r.number(o, "occlusion", "gap_m", so.gap, 1e-3, 0.5);
    so.height = r.number(o, "occlusion", "height_m", so.height, 1e-3, 0.5);
    so.follow_base = r.boolean(o, "occlusion", "follow_base", so.follow_base);
    if (so.fraction > 0) {
      if (s.occluders.size() >= static_cast<std::size_t>(kMaxOccluders))
        r.fail(o, "occlusion", "at most " + std::to_string(kMaxOccluders) + " occluders in all");
      try {
        s.occluders.push_back(
            screen_occluder(so, s.chain.geometry, s.base, s.camera, s.duration_s));
      } catch (const std::invalid_argument& e) {
        // "occlusion.gap_m = ...: ..." names its own key; the rest are about the block.
        const std::string what = e.what();
        const std::size_t eq = what.find(" = ");
        if (what.rfind("occlusion.", 0) == 0 && eq != std::string::npos) {
          const std::string key = what.substr(0, eq);
          const YAML::Node at = o[key.substr(10)];
          r.fail(at ? at : o, key, what.substr(eq + 3));  // "<value>: <rule>"
        }
        r.fail(o, "occlusion", what);
      }
    }
  }
  s.tracker.geometry = s.chain.geometry;
  s.tracker.nodes = s.chain.geometry.count + 1;
  s.tracker.policy.lsq_init.pitch = s.chain.geometry.pitch;
  s.tracker.policy.som_init.seed = derive_seed(s.seed, "tracker");
  if (const YAML::Node t = root["tracker"]) read_tracker(r, t, s.tracker);
  try {
    s.chain.validate();
    s.world.validate();
    s.noise.validate();
    s.segmentation.validate();
    s.tracker.validate();
  } catch (const std::invalid_argument& e) {
    throw io::InputError(file + ": " + e.what());
  }
  return s;
}

std::unique_ptr<World> make_world(const Scene& scene) {
  auto w = std::make_unique<World>(scene.chain, scene.world, scene.base.pose(0.0));
  w->set_base_trajectory(scene.base);
  for (const auto& f : scene.forces) w->add_force(f);
  for (const auto& g : scene.gravity_switches) w->add_gravity_switch(g);
  for (const auto& p : scene.pushers) w->add_pusher(p);
  for (const auto& o : scene.obstacles) w->add_obstacle(o);
  return w;
}

int camera_frames(const Scene& scene, int requested) {
  return requested > 0 ? requested : static_cast<int>(scene.duration_s * scene.camera.fps) + 1;
}

std::unique_ptr<Sensor> make_sensor(const Scene& scene, int threads) {
  SensorParams p;
  p.camera = scene.camera;
  p.noise = scene.noise;
  p.threads = threads;
  return std::make_unique<Sensor>(p, scene.chain.geometry, scene.occluders, scene.background);
}

}  // namespace linksight::sim
