#include "linksight/sim/scene.hpp"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <numbers>
#include <set>
#include <string>

#include "linksight/io/error.hpp"

namespace linksight::sim {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

// Reads typed values out of YAML nodes, rejecting unknown keys, with file:line in errors.
class Reader {
 public:
  explicit Reader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(const YAML::Node& node, const std::string& key,
                         const std::string& what) const {
    const int line = node.IsDefined() ? node.Mark().line + 1 : 0;
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

 private:
  std::string file_;
};

}  // namespace

Scene load_scene(const std::filesystem::path& path) {
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
  const Reader r(file);
  if (!root.IsMap()) r.fail(root, "(top level)", "expected a mapping");
  r.only(root, "", {"duration_s", "seed", "camera", "chain", "world", "base", "actions"});
  Scene s;
  s.duration_s = r.number(root, "", "duration_s", s.duration_s, 1e-3, 3600.0);
  s.seed = static_cast<std::uint64_t>(r.number(root, "", "seed", 1.0, 0.0, 9007199254740992.0));
  if (const YAML::Node c = root["camera"]) {
    r.only(c, "camera", {"fps"});
    s.camera_fps = r.number(c, "camera", "fps", s.camera_fps, 1.0, 1000.0);
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
  try {
    s.chain.validate();
    s.world.validate();
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

}  // namespace linksight::sim
