#include "linksight/sim/scene.hpp"

#include "linksight/sim/mesh.hpp"
#include "linksight/sim/occlusion.hpp"

#include "linksight/sim/yaml.hpp"

#include <cmath>
#include <memory>
#include <numbers>
#include <set>
#include <sstream>
#include <string>

#include "linksight/io/error.hpp"
#include "linksight/tracker/format.hpp"
#include "linksight/tracker/seed.hpp"

namespace linksight::sim {
namespace {

constexpr double kDeg = fields::deg({}).scale;

using yaml::Reader;

// What is not a struct's field: a pose (position_m, rpy_deg), the table (a box made from
// its top face), noise.scale, duration_s; their rules are the ones given here.
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
Eigen::Vector3d vec3(const Reader& r, const YAML::Node& map, const std::string& where,
                     const char* key, const Eigen::Vector3d& fallback) {
  const YAML::Node n = map[key];
  return n ? r.vec3(n, yaml::join(where, key)) : fallback;
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

// Reads one item of a list into `x` (its field list plus `extra` keys, read by the
// caller in `more`), then validates it at its path.
template <class T, class More, class Validate>
T item(const Reader& r, const YAML::Node& n, const std::string& at,
       const std::set<std::string>& extra, More&& more, Validate&& validate) {
  T x;
  yaml::read(r, n, at, x, extra);
  more(x);
  yaml::validated(r, n, at, [&] { validate(x); });
  return x;
}

// The items of list `key` in `map` (absent: none), each read by `read(node, path)`.
template <class F>
void each(const Reader& r, const YAML::Node& map, const std::string& where, const char* key,
          F&& read) {
  const YAML::Node list = map[key];
  if (!list) return;
  const std::string name = yaml::join(where, key);
  if (!list.IsSequence()) r.fail(list, name, "expected a list");
  for (std::size_t i = 0; i < list.size(); ++i)
    read(list[i], name + "[" + std::to_string(i) + "]");
}

BaseTrajectory trajectory(const Reader& r, const YAML::Node& map, const std::string& where) {
  r.only(map, where, {"waypoints", "sweeps"});
  std::vector<Waypoint> wps;
  each(r, map, where, "waypoints", [&](const YAML::Node& n, const std::string& at) {
    wps.push_back(item<Waypoint>(
        r, n, at, {"position_m", "rpy_deg"}, [&](Waypoint& w) { w.X_WB = pose(r, n, at); },
        [](const Waypoint& w) { w.validate(); }));
  });
  std::vector<Sweep> sweeps;
  each(r, map, where, "sweeps", [&](const YAML::Node& n, const std::string& at) {
    sweeps.push_back(item<Sweep>(r, n, at, {}, [](Sweep&) {}, [](const Sweep& s) { s.validate(); }));
  });
  try {
    return BaseTrajectory(std::move(wps), std::move(sweeps));
  } catch (const std::invalid_argument& e) {
    r.fail(map, where, e.what());
  }
}

// A shaped item's mesh file, relative to the scene's folder `base`.
void read_mesh(const Reader& r, const YAML::Node& map, const std::string& where,
               const std::filesystem::path& base, Shape& sh) {
  if (sh.kind == Shape::Kind::mesh) {
    if (!map["mesh"]) r.fail(map, where + ".mesh", "a mesh shape needs a mesh file");
    const std::filesystem::path file = r.text(map["mesh"], where + ".mesh");
    sh.mesh = file.is_absolute() ? file : base / file;
    std::error_code ec;
    if (!std::filesystem::is_regular_file(sh.mesh, ec))
      r.fail(map["mesh"], where + ".mesh", sh.mesh.string() + ": mesh file not found");
    // Read now, so that a file that is no mesh (/etc/passwd, a truncated OBJ) is an error
    // naming the scene's key, not the sensor's later. A mesh is only ever read.
    try {
      sh.mesh_data = std::make_shared<const TriangleMesh>(load_mesh(sh.mesh));
    } catch (const io::InputError& e) {
      r.fail(map["mesh"], where + ".mesh", e.what());
    }
  } else if (map["mesh"]) {
    r.fail(map["mesh"], where + ".mesh", "only for shape: mesh");
  }
}

void read_camera(const Reader& r, const YAML::Node& c, CameraParams& cam) {
  if (!c.IsMap()) r.fail(c, "camera", "expected a mapping");
  if (c["look_at"] && c["X_WC"]) r.fail(c["X_WC"], "camera.X_WC", "give look_at or X_WC, not both");
  yaml::read(r, c, "camera", cam, {"preset", "look_at"});
  if (const YAML::Node p = c["preset"]) {
    const std::string name = r.text(p, "camera.preset");
    if (name != "sr300")
      r.fail(p, "camera.preset", "unknown camera preset '" + io::echo(name) + "' (expected sr300)");
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
  yaml::validated(r, n, "noise", [&] { noise.validate(); });  // the values the file gives
  // One knob for sweeps: scales every random term (axial sigma, ray jitter) after the
  // blocks above; dropouts, edges and shadows are left as they are.
  const double scale = number(r, n, "noise", "scale", 1.0, 0.0, 100.0);
  noise.axial.a *= scale;
  noise.axial.c *= scale;
  noise.axial.k_theta *= scale;
  noise.lateral.sigma_px *= scale;
  try {
    noise.validate();
  } catch (const fields::FieldError& e) {
    r.fail(n["scale"] ? n["scale"] : n, "noise.scale",
           "= " + format_shortest(scale) + " makes noise." + e.key() + " " + e.value() + ", which " +
               e.rule());
  }
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
  each(r, b, "background", "objects", [&](const YAML::Node& n, const std::string& at) {
    out.push_back(item<BackgroundObject>(
        r, n, at, {"mesh", "position_m", "rpy_deg"},
        [&](BackgroundObject& o) {
          read_mesh(r, n, at, base, o.shape);
          o.X_WO = pose(r, n, at);
        },
        [](const BackgroundObject& o) { o.shape.validate(); }));
  });
}

void read_occluders(const Reader& r, const YAML::Node& root, const std::filesystem::path& base,
                    std::vector<Occluder>& out) {
  if (root["occluders"] && root["occluders"].size() > static_cast<std::size_t>(kMaxOccluders))
    r.fail(root["occluders"], "occluders", "at most " + std::to_string(kMaxOccluders));
  each(r, root, "", "occluders", [&](const YAML::Node& n, const std::string& at) {
    out.push_back(item<Occluder>(
        r, n, at, {"mesh", "path", "from_s", "to_s"},
        [&](Occluder& oc) {
          read_mesh(r, n, at, base, oc.shape);
          if (const YAML::Node route = n["path"]) oc.path = trajectory(r, route, at + ".path");
          // Absent, a bound is open: there from the start, or to the end.
          if (n["from_s"]) oc.from_s = r.number(n["from_s"], at + ".from_s");
          if (n["to_s"]) oc.to_s = r.number(n["to_s"], at + ".to_s");
        },
        [](const Occluder& oc) { oc.validate(); }));
  });
}

void read_actions(const Reader& r, const YAML::Node& a, Scene& s) {
  r.only(a, "actions", {"forces", "gravity", "pushers", "obstacles"});
  each(r, a, "actions", "gravity", [&](const YAML::Node& n, const std::string& at) {
    s.gravity_switches.push_back(item<GravityAction>(
        r, n, at, {}, [](GravityAction&) {}, [](const GravityAction& g) { g.validate(); }));
  });
  each(r, a, "actions", "forces", [&](const YAML::Node& n, const std::string& at) {
    s.forces.push_back(item<ForceAction>(
        r, n, at, {},
        [&](ForceAction& f) {
          if (!n["t_end_s"]) f.t_end = f.t_start;  // absent: a force of one instant
        },
        [&](const ForceAction& f) { f.validate(s.chain.geometry.count); }));
  });
  each(r, a, "actions", "pushers", [&](const YAML::Node& n, const std::string& at) {
    s.pushers.push_back(item<PusherParams>(
        r, n, at, {"path"},
        [&](PusherParams& p) {
          if (const YAML::Node route = n["path"]) p.path = trajectory(r, route, at + ".path");
        },
        [](const PusherParams& p) { p.validate(); }));
  });
  each(r, a, "actions", "obstacles", [&](const YAML::Node& n, const std::string& at) {
    s.obstacles.push_back(item<ObstacleParams>(
        r, n, at, {"position_m", "rpy_deg"}, [&](ObstacleParams& o) { o.X_WO = pose(r, n, at); },
        [](const ObstacleParams& o) { o.validate(); }));
  });
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
    "segmentation", "chain", "world", "base", "actions", "tracker", "external"};

// The scene and the YAML tree it was read from (after the overrides).
std::pair<Scene, YAML::Node> load(const std::filesystem::path& path,
                                  const std::vector<std::string>& overrides,
                                  const std::vector<std::string>& axis = {}) {
  const std::string file = path.string();
  YAML::Node root = yaml::load_file(path, "scene");
  if (!root.IsMap()) Reader(file).fail(root, "(top level)", "expected a mapping");
  std::vector<yaml::Override> applied;
  for (const std::string& o : overrides) applied.push_back(yaml::apply_override(file, root, o));
  for (const std::string& o : axis)
    applied.push_back(yaml::apply_override(file, root, o, "--axis"));
  const Reader r(file, applied);
  r.only(root, "", kTopKeys);
  const std::filesystem::path base = path.parent_path();
  Scene s;
  s.duration_s = number(r, root, "", "duration_s", s.duration_s, 1e-3, kMaxDurationS);
  if (const YAML::Node n = root["seed"])
    s.seed = static_cast<std::uint64_t>(r.integer(n, "seed", 0, 9007199254740994.0));  // [0, 2^53]
  if (const YAML::Node c = root["camera"]) read_camera(r, c, s.camera);
  if (const YAML::Node n = root["noise"]) read_noise(r, n, s.noise);
  if (const YAML::Node n = root["segmentation"]) read_segmentation(r, n, s.segmentation);
  if (const YAML::Node b = root["background"]) read_background(r, b, base, s.background);
  read_occluders(r, root, base, s.occluders);
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
  s.tracker.policy.chain_fit.cone_limit = s.chain.cone_limit;
  const YAML::Node tracker = root["tracker"] ? root["tracker"] : root;
  if (root["tracker"]) yaml::read(r, tracker, "tracker", s.tracker);
  yaml::validated(r, tracker, "tracker", [&] { s.tracker.validate(); });
  if (const YAML::Node e = root["external"]) {
    yaml::read(r, e, "external", s.external);
    yaml::validated(r, e, "external", [&] { s.external.validate(); });
  }
  return {std::move(s), root};
}

}  // namespace

Scene load_scene(const std::filesystem::path& path, const std::vector<std::string>& overrides,
                 const std::vector<std::string>& axis) {
  return load(path, overrides, axis).first;
}

std::string resolved_scene_yaml(const std::filesystem::path& path,
                                const std::vector<std::string>& overrides) {
  // Not a structured binding: clang before 16 (the fuzz build's) cannot capture one.
  const auto loaded = load(path, overrides);
  const Scene& s = loaded.first;
  const YAML::Node& root = loaded.second;
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
  yaml::write(y, "external", s.external);
  // A mesh path is relative to the scene's folder: write the file it resolved to, so the
  // printed scene loads from anywhere.
  const auto resolve_meshes = [](YAML::Node list, auto shape_of) {
    for (std::size_t i = 0; list.IsSequence() && i < list.size(); ++i)
      if (list[i]["mesh"])
        list[i]["mesh"] = std::filesystem::absolute(shape_of(i).mesh).lexically_normal().string();
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
