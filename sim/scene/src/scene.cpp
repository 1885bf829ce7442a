#include "linksight/sim/scene.hpp"

#include "linksight/sim/occlusion.hpp"

#include "linksight/sim/yaml.hpp"

#include <cmath>
#include <numbers>
#include <set>
#include <sstream>
#include <string>

#include "linksight/io/error.hpp"
#include "linksight/tracker/format.hpp"
#include "linksight/tracker/seed.hpp"

namespace linksight::sim {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

using yaml::Reader;

// Composite items (poses, paths, shapes, actions) are read here, not through a parameter
// struct's field list; their number rules are the ones below.
double number(const Reader& r, const YAML::Node& map, const std::string& where, const char* key,
              double fallback, double lo, double hi) {
  const YAML::Node n = map[key];
  if (!n) return fallback;
  const std::string name = yaml::join(where, key);
  const double v = r.number(n, name);
  if (!fields::obeys(fields::in(lo, hi), v))
    r.fail(n, name, "= " + format_shortest(v) + ": " + fields::describe(fields::in(lo, hi)));
  return v;
}
bool boolean(const Reader& r, const YAML::Node& map, const std::string& where, const char* key,
             bool fallback) {
  const YAML::Node n = map[key];
  return n ? r.boolean(n, yaml::join(where, key)) : fallback;
}
Eigen::Vector3d vec3(const Reader& r, const YAML::Node& map, const std::string& where,
                     const char* key, const Eigen::Vector3d& fallback) {
  const YAML::Node n = map[key];
  return n ? r.vec3(n, yaml::join(where, key)) : fallback;
}
template <class E, class Parse>
E choice(const Reader& r, const YAML::Node& map, const std::string& where, const char* key,
         E fallback, Parse parse) {
  E v = fallback;
  yaml::In(r, map, where)(key, v, parse);
  return v;
}

// A pose: position_m [x, y, z] and rpy_deg [roll, pitch, yaw] (fixed axes x, y, z).
Eigen::Isometry3d pose(const Reader& r, const YAML::Node& map, const std::string& where) {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.translation() = vec3(r, map, where, "position_m", Eigen::Vector3d::Zero());
  const Eigen::Vector3d rpy = vec3(r, map, where, "rpy_deg", Eigen::Vector3d::Zero()) * kDeg;
  X.linear() = (Eigen::AngleAxisd(rpy.z(), Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(rpy.y(), Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(rpy.x(), Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  return X;
}

BaseTrajectory trajectory(const Reader& r, const YAML::Node& map, const std::string& where) {
  r.only(map, where, {"waypoints", "sweeps"});
  std::vector<Waypoint> wps;
  if (const YAML::Node w = map["waypoints"]) {
    if (!w.IsSequence()) r.fail(w, where + ".waypoints", "expected a list");
    for (std::size_t i = 0; i < w.size(); ++i) {
      const std::string at = where + ".waypoints[" + std::to_string(i) + "]";
      r.only(w[i], at, {"t_s", "position_m", "rpy_deg"});
      wps.push_back({number(r, w[i], at, "t_s", 0.0, 0.0, 1e6), pose(r, w[i], at)});
    }
  }
  std::vector<Sweep> sweeps;
  if (const YAML::Node s = map["sweeps"]) {
    if (!s.IsSequence()) r.fail(s, where + ".sweeps", "expected a list");
    for (std::size_t i = 0; i < s.size(); ++i) {
      const std::string at = where + ".sweeps[" + std::to_string(i) + "]";
      r.only(s[i], at, {"axis", "amplitude_deg", "offset_m", "frequency_hz", "phase_deg"});
      Sweep sw;
      sw.axis_B = vec3(r, s[i], at, "axis", sw.axis_B);
      if (sw.axis_B.norm() < 1e-9) r.fail(s[i]["axis"], at + ".axis", "must not be zero");
      sw.amplitude = number(r, s[i], at, "amplitude_deg", 0.0, -180, 180) * kDeg;
      sw.offset_W = vec3(r, s[i], at, "offset_m", sw.offset_W);
      sw.frequency = number(r, s[i], at, "frequency_hz", sw.frequency, 0.0, 100.0);
      sw.phase = number(r, s[i], at, "phase_deg", 0.0, -360, 360) * kDeg;
      sweeps.push_back(sw);
    }
  }
  try {
    return BaseTrajectory(std::move(wps), std::move(sweeps));
  } catch (const std::invalid_argument& e) {
    r.fail(map, where, e.what());
  }
}

// shape: box | cylinder | sphere | mesh, with its sizes. `base` resolves mesh paths.
Shape shape(const Reader& r, const YAML::Node& map, const std::string& where,
            const std::filesystem::path& base) {
  Shape sh;
  sh.kind = choice(r, map, where, "shape", Shape::Kind::box, parse_shape_kind);
  sh.half_extents = vec3(r, map, where, "half_extents_m", sh.half_extents);
  if (!(sh.half_extents.minCoeff() > 0))
    r.fail(map["half_extents_m"], where + ".half_extents_m", "must all be > 0");
  sh.radius = number(r, map, where, "radius_m", sh.radius, 1e-4, 10.0);
  sh.half_length = number(r, map, where, "half_length_m", sh.half_length, 1e-4, 10.0);
  sh.scale = number(r, map, where, "scale", sh.scale, 1e-6, 1e6);
  if (sh.kind == Shape::Kind::mesh) {
    if (!map["mesh"]) r.fail(map, where + ".mesh", "a mesh shape needs a mesh file");
    const std::filesystem::path file = r.text(map["mesh"], where + ".mesh");
    sh.mesh = file.is_absolute() ? file : base / file;
    std::error_code ec;
    if (!std::filesystem::is_regular_file(sh.mesh, ec))
      r.fail(map["mesh"], where + ".mesh", sh.mesh.string() + ": mesh file not found");
  } else if (map["mesh"]) {
    r.fail(map["mesh"], where + ".mesh", "only for shape: mesh");
  }
  return sh;
}

const std::set<std::string> kShapeKeys = {"shape",  "half_extents_m", "radius_m", "half_length_m",
                                          "mesh",   "scale",          "reflectance"};

std::set<std::string> with(std::set<std::string> keys, std::initializer_list<const char*> more) {
  for (const char* k : more) keys.insert(k);
  return keys;
}

void read_camera(const Reader& r, const YAML::Node& c, CameraParams& cam) {
  if (!c.IsMap()) r.fail(c, "camera", "expected a mapping");
  if (c["look_at"] && c["X_WC"]) r.fail(c["X_WC"], "camera.X_WC", "give look_at or X_WC, not both");
  yaml::read(r, c, "camera", cam, {"preset", "look_at"});
  if (const YAML::Node p = c["preset"]) {
    const std::string name = r.text(p, "camera.preset");
    if (name != "sr300")
      r.fail(p, "camera.preset", "unknown camera preset '" + name + "' (expected sr300)");
  }
  if (const YAML::Node l = c["look_at"]) {
    r.only(l, "camera.look_at", {"eye_m", "target_m", "up"});
    try {
      cam.X_WC = look_at(vec3(r, l, "camera.look_at", "eye_m", {0.25, -0.6, 0.6}),
                         vec3(r, l, "camera.look_at", "target_m", {0.25, 0.0, 0.45}),
                         vec3(r, l, "camera.look_at", "up", Eigen::Vector3d::UnitZ()));
    } catch (const std::invalid_argument& e) {
      r.fail(l, "camera.look_at", e.what());
    }
  }
  yaml::validated(r, c, "camera", [&] { cam.validate(); });
}

void read_noise(const Reader& r, const YAML::Node& n, NoiseParams& noise) {
  if (!n.IsMap()) r.fail(n, "noise", "expected a mapping");
  std::string preset = "sr300";
  if (const YAML::Node p = n["preset"]) preset = r.text(p, "noise.preset");
  try {
    noise = NoiseParams::preset(preset);
  } catch (const std::invalid_argument& e) {
    r.fail(n["preset"], "noise.preset", e.what());
  }
  // A term's block switches the term on unless it says `enabled: false` (so a block
  // under `preset: off` means what it says).
  if (n["axial"]) noise.axial.enabled = true;
  if (n["lateral"]) noise.lateral.enabled = true;
  if (n["shadow"]) noise.shadow.enabled = true;
  if (n["dropouts"]) noise.dropouts.enabled = true;
  if (n["edges"]) noise.edges.enabled = true;
  yaml::read(r, n, "noise", noise, {"preset", "scale"});
  // One knob for sweeps: scales every random term (axial sigma, ray jitter) after the
  // blocks above; dropouts, edges and shadows are left as they are.
  const double scale = number(r, n, "noise", "scale", 1.0, 0.0, 100.0);
  noise.axial.a *= scale;
  noise.axial.c *= scale;
  noise.axial.k_theta *= scale;
  noise.lateral.sigma_px *= scale;
  yaml::validated(r, n, "noise", [&] { noise.validate(); });
}

void read_segmentation(const Reader& r, const YAML::Node& n, ExtractParams& p) {
  const char* w = "segmentation";
  yaml::read(r, n, w, p, {"crop_min_m", "crop_max_m"});
  if (n["crop_min_m"] || n["crop_max_m"]) {
    if (!n["crop_min_m"] || !n["crop_max_m"])
      r.fail(n, "segmentation.crop_min_m", "give crop_min_m and crop_max_m together");
    p.crop_C = Eigen::AlignedBox3d(vec3(r, n, w, "crop_min_m", Eigen::Vector3d::Zero()),
                                   vec3(r, n, w, "crop_max_m", Eigen::Vector3d::Zero()));
  }
  yaml::validated(r, n, w, [&] { p.validate(); });
}

void read_background(const Reader& r, const YAML::Node& b, const std::filesystem::path& base,
                     std::vector<BackgroundObject>& out) {
  r.only(b, "background", {"table", "wall", "objects"});
  if (const YAML::Node t = b["table"]) {
    r.only(t, "background.table", {"height_m", "center_m", "half_size_m", "reflectance"});
    BackgroundObject o;
    const double h = number(r, t, "background.table", "height_m", 0.3, -10, 10);
    const Eigen::Vector3d c = vec3(r, t, "background.table", "center_m", {0.25, 0.0, 0.0});
    const Eigen::Vector3d hs = vec3(r, t, "background.table", "half_size_m", {0.6, 0.6, 0.01});
    if (!(hs.minCoeff() > 0)) r.fail(t["half_size_m"], "background.table.half_size_m", "must all be > 0");
    o.shape.half_extents = hs;
    o.X_WO.translation() = Eigen::Vector3d(c.x(), c.y(), h - hs.z());  // top face at height_m
    o.reflectance = number(r, t, "background.table", "reflectance", 1.0, 0, 10);
    out.push_back(o);
  }
  if (const YAML::Node wl = b["wall"]) {
    r.only(wl, "background.wall", {"position_m", "rpy_deg", "half_extents_m", "reflectance"});
    BackgroundObject o;
    o.shape.half_extents = vec3(r, wl, "background.wall", "half_extents_m", {1.0, 0.01, 1.0});
    if (!(o.shape.half_extents.minCoeff() > 0))
      r.fail(wl["half_extents_m"], "background.wall.half_extents_m", "must all be > 0");
    o.X_WO = pose(r, wl, "background.wall");
    o.reflectance = number(r, wl, "background.wall", "reflectance", 1.0, 0, 10);
    out.push_back(o);
  }
  if (const YAML::Node objs = b["objects"]) {
    if (!objs.IsSequence()) r.fail(objs, "background.objects", "expected a list");
    for (std::size_t i = 0; i < objs.size(); ++i) {
      const std::string at = "background.objects[" + std::to_string(i) + "]";
      r.only(objs[i], at, with(kShapeKeys, {"position_m", "rpy_deg"}));
      BackgroundObject o;
      o.shape = shape(r, objs[i], at, base);
      o.X_WO = pose(r, objs[i], at);
      o.reflectance = number(r, objs[i], at, "reflectance", 1.0, 0, 10);
      out.push_back(o);
    }
  }
}

void read_occluders(const Reader& r, const YAML::Node& o, const std::filesystem::path& base,
                    std::vector<Occluder>& out) {
  if (!o.IsSequence()) r.fail(o, "occluders", "expected a list");
  if (o.size() > static_cast<std::size_t>(kMaxOccluders))
    r.fail(o, "occluders", "at most " + std::to_string(kMaxOccluders));
  for (std::size_t i = 0; i < o.size(); ++i) {
    const std::string at = "occluders[" + std::to_string(i) + "]";
    r.only(o[i], at, with(kShapeKeys, {"path", "from_s", "to_s"}));
    Occluder oc;
    oc.shape = shape(r, o[i], at, base);
    oc.reflectance = number(r, o[i], at, "reflectance", 1.0, 0, 10);
    if (const YAML::Node route = o[i]["path"]) oc.path = trajectory(r, route, at + ".path");
    oc.from_s = number(r, o[i], at, "from_s", 0.0, 0.0, 1e6);
    if (o[i]["to_s"]) {
      oc.to_s = number(r, o[i], at, "to_s", 0.0, 0.0, 1e6);
      if (!(oc.to_s > oc.from_s))
        r.fail(o[i]["to_s"], at + ".to_s",
               "= " + format_shortest(oc.to_s) + ": must be > from_s (" +
                   format_shortest(oc.from_s) + ")");
    }
    if (!o[i]["from_s"]) oc.from_s = -std::numeric_limits<double>::infinity();
    out.push_back(oc);
  }
}

void read_actions(const Reader& r, const YAML::Node& a, Scene& s) {
  r.only(a, "actions", {"forces", "gravity", "pushers", "obstacles"});
  auto list = [&](const char* key) {
    const YAML::Node l = a[key];
    if (l && !l.IsSequence()) r.fail(l, std::string("actions.") + key, "expected a list");
    return l;
  };
  if (const YAML::Node gv = list("gravity")) {
    for (std::size_t i = 0; i < gv.size(); ++i) {
      const std::string at = "actions.gravity[" + std::to_string(i) + "]";
      r.only(gv[i], at, {"t_s", "on"});
      s.gravity_switches.push_back(
          {number(r, gv[i], at, "t_s", 0.0, 0.0, 1e6), boolean(r, gv[i], at, "on", true)});
    }
  }
  if (const YAML::Node f = list("forces")) {
    for (std::size_t i = 0; i < f.size(); ++i) {
      const std::string at = "actions.forces[" + std::to_string(i) + "]";
      r.only(f[i], at, {"component", "force_n", "torque_nm", "t_start_s", "t_end_s"});
      ForceAction fa;
      fa.component =
          static_cast<int>(number(r, f[i], at, "component", 0, 0, s.chain.geometry.count - 1));
      fa.force_W = vec3(r, f[i], at, "force_n", fa.force_W);
      fa.torque_W = vec3(r, f[i], at, "torque_nm", fa.torque_W);
      fa.t_start = number(r, f[i], at, "t_start_s", 0.0, 0.0, 1e6);
      fa.t_end = number(r, f[i], at, "t_end_s", fa.t_start, fa.t_start, 1e6);
      s.forces.push_back(fa);
    }
  }
  if (const YAML::Node p = list("pushers")) {
    for (std::size_t i = 0; i < p.size(); ++i) {
      const std::string at = "actions.pushers[" + std::to_string(i) + "]";
      PusherParams pp;
      yaml::read(r, p[i], at, pp, {"path"});
      if (const YAML::Node route = p[i]["path"]) pp.path = trajectory(r, route, at + ".path");
      yaml::validated(r, p[i], at, [&] { pp.validate(); });
      s.pushers.push_back(pp);
    }
  }
  if (const YAML::Node o = list("obstacles")) {
    for (std::size_t i = 0; i < o.size(); ++i) {
      const std::string at = "actions.obstacles[" + std::to_string(i) + "]";
      r.only(o[i], at, {"half_extents_m", "position_m", "rpy_deg"});
      ObstacleParams op;
      op.half_extents = vec3(r, o[i], at, "half_extents_m", op.half_extents);
      if (!(op.half_extents.minCoeff() > 0))
        r.fail(o[i]["half_extents_m"], at + ".half_extents_m", "must all be > 0");
      op.X_WO = pose(r, o[i], at);
      s.obstacles.push_back(op);
    }
  }
}

void read_occlusion(const Reader& r, const YAML::Node& o, Scene& s) {
  ScreenOcclusion& so = s.occlusion;
  yaml::read(r, o, "occlusion", so);
  yaml::validated(r, o, "occlusion", [&] { so.validate(); });
  if (so.fraction > 0) {
    if (s.occluders.size() >= static_cast<std::size_t>(kMaxOccluders))
      r.fail(o, "occlusion", "at most " + std::to_string(kMaxOccluders) + " occluders in all");
    yaml::validated(r, o, "occlusion", [&] {
      s.occluders.push_back(screen_occluder(so, s.chain.geometry, s.base, s.camera, s.duration_s));
    });
  }
}

const std::set<std::string> kTopKeys = {
    "duration_s", "seed",  "camera", "noise",   "occluders", "occlusion", "background",
    "segmentation", "chain", "world", "base", "actions", "tracker"};

// The scene and the YAML tree it was read from (after the overrides).
std::pair<Scene, YAML::Node> load(const std::filesystem::path& path,
                                  const std::vector<std::string>& overrides) {
  const std::string file = path.string();
  YAML::Node root = yaml::load_file(path, "scene");
  if (!root.IsMap()) Reader(file).fail(root, "(top level)", "expected a mapping");
  std::vector<yaml::Override> applied;
  for (const std::string& o : overrides) applied.push_back(yaml::apply_override(file, root, o));
  const Reader r(file, applied);
  r.only(root, "", kTopKeys);
  const std::filesystem::path base = path.parent_path();
  Scene s;
  s.duration_s = number(r, root, "", "duration_s", s.duration_s, 1e-3, 3600.0);
  if (const YAML::Node n = root["seed"])
    s.seed = static_cast<std::uint64_t>(r.integer(n, "seed", 0, 9007199254740992.0));  // 2^53
  if (const YAML::Node c = root["camera"]) read_camera(r, c, s.camera);
  if (const YAML::Node n = root["noise"]) read_noise(r, n, s.noise);
  if (const YAML::Node n = root["segmentation"]) read_segmentation(r, n, s.segmentation);
  if (const YAML::Node b = root["background"]) read_background(r, b, base, s.background);
  if (const YAML::Node o = root["occluders"]) read_occluders(r, o, base, s.occluders);
  const YAML::Node chain = root["chain"] ? root["chain"] : root;
  if (root["chain"]) yaml::read(r, chain, "chain", s.chain);
  yaml::validated(r, chain, "chain", [&] { s.chain.validate(); });
  const YAML::Node world = root["world"] ? root["world"] : root;
  if (root["world"]) yaml::read(r, world, "world", s.world);
  yaml::validated(r, world, "world", [&] { s.world.validate(); });
  if (const YAML::Node b = root["base"]) s.base = trajectory(r, b, "base");
  if (const YAML::Node a = root["actions"]) read_actions(r, a, s);
  if (const YAML::Node o = root["occlusion"]) read_occlusion(r, o, s);
  s.tracker.geometry = s.chain.geometry;
  s.tracker.nodes = s.chain.geometry.count + 1;
  s.tracker.policy.lsq_init.pitch = s.chain.geometry.pitch;
  s.tracker.policy.som_init.seed = derive_seed(s.seed, "tracker");
  const YAML::Node tracker = root["tracker"] ? root["tracker"] : root;
  if (root["tracker"]) yaml::read(r, tracker, "tracker", s.tracker);
  yaml::validated(r, tracker, "tracker", [&] { s.tracker.validate(); });
  return {std::move(s), root};
}

}  // namespace

Scene load_scene(const std::filesystem::path& path, const std::vector<std::string>& overrides) {
  return load(path, overrides).first;
}

std::string resolved_scene_yaml(const std::filesystem::path& path,
                                const std::vector<std::string>& overrides) {
  const auto [s, root] = load(path, overrides);
  std::ostringstream y;
  y << "# " << path.string() << ", resolved by linksight";
  for (const std::string& o : overrides) y << " --set " << o;
  y << "\n# every parameter block in full; the lists (base, occluders, background, actions)\n"
    << "# as given, with mesh files as the paths they resolved to\n";
  y << "duration_s: " << format_shortest(s.duration_s) << "\n";
  y << "seed: " << s.seed << "\n";
  yaml::write(y, "camera", s.camera);
  yaml::write(y, "noise", s.noise);
  yaml::write(y, "segmentation", s.segmentation);
  if (s.segmentation.crop_C) {
    const auto v = [](const Eigen::Vector3d& p) {
      std::string t = "[";
      for (int i = 0; i < 3; ++i) (t += i ? ", " : "") += format_shortest(p[i]);
      return t + "]";
    };
    y << "  crop_min_m: " << v(s.segmentation.crop_C->min()) << "\n"
      << "  crop_max_m: " << v(s.segmentation.crop_C->max()) << "\n";
  }
  yaml::write(y, "chain", s.chain);
  yaml::write(y, "world", s.world);
  yaml::write(y, "occlusion", s.occlusion);
  yaml::write(y, "tracker", s.tracker);
  // A mesh path is relative to the scene's folder: write the file it resolved to, so the
  // printed scene loads from anywhere.
  const auto resolve_meshes = [](YAML::Node list, auto shape_of) {
    for (std::size_t i = 0; list.IsSequence() && i < list.size(); ++i)
      if (list[i]["mesh"]) list[i]["mesh"] = shape_of(i).mesh.string();
  };
  for (const char* key : {"base", "occluders", "background", "actions"}) {
    if (!root[key]) continue;
    YAML::Node block = YAML::Clone(root[key]);
    if (std::string(key) == "occluders")
      resolve_meshes(block, [&](std::size_t i) { return s.occluders[i].shape; });
    if (std::string(key) == "background" && block["objects"]) {
      const std::size_t first = (block["table"] ? 1 : 0) + (block["wall"] ? 1 : 0);
      resolve_meshes(block["objects"], [&](std::size_t i) { return s.background[first + i].shape; });
    }
    YAML::Emitter e;
    e << YAML::BeginMap << YAML::Key << key << YAML::Value << block << YAML::EndMap;
    y << e.c_str() << "\n";
  }
  return y.str();
}

std::string noise_yaml(const NoiseParams& noise) {
  std::ostringstream y;
  yaml::write(y, "noise", noise);
  return y.str();
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
