// Scene files: the shipped physics scenes do what their comments say; bad files name
// the file, the line and the key.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <fstream>
#include <limits>
#include <set>
#include <vector>

#include "linksight/io/echo.hpp"
#include "linksight/io/error.hpp"
#include "linksight/sim/scene.hpp"
#include "linksight/sim/yaml.hpp"
#include "test_support.hpp"

namespace linksight::sim {
namespace {

const std::filesystem::path kScenes = LINKSIGHT_SCENE_DIR;

Truth run_until(World& w, double t) {
  while (w.time() + 1e-9 < t) w.step();
  return w.truth();
}

TEST(Scene, StaticHoldsTheChain) {
  const Scene s = load_scene(kScenes / "static.yaml");
  EXPECT_DOUBLE_EQ(s.duration_s, 5.0);
  EXPECT_DOUBLE_EQ(s.chain.preload_force, 450.0);
  auto w = make_world(s);
  const Truth start = w->truth();
  const Truth end = run_until(*w, s.duration_s);
  EXPECT_LT((end.nodes_W.back() - start.nodes_W.back()).norm(), 0.0005);
  EXPECT_FALSE(end.contact);
}

// The push bends the chain within the first 4 s; afterwards it keeps the shape.
TEST(Scene, BendPushBendsThenHolds) {
  const Scene s = load_scene(kScenes / "bend_push.yaml");
  ASSERT_EQ(s.pushers.size(), 1u);
  auto w = make_world(s);
  const Truth start = w->truth();
  bool touched = false;
  while (w->time() < 4.0) {
    w->step();
    touched |= w->truth().contact;
  }
  const Truth at4 = w->truth();
  EXPECT_TRUE(touched);
  EXPECT_GT((at4.nodes_W.back() - start.nodes_W.back()).norm(), 0.05);
  const Truth end = run_until(*w, 6.0);
  for (std::size_t j = 0; j < end.nodes_W.size(); ++j) {
    EXPECT_LT((end.nodes_W[j] - at4.nodes_W[j]).norm(), 0.001) << "node " << j;
  }
}

class BadScene : public ::testing::Test {
 protected:
  std::filesystem::path dir =
      test::scratch_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
  // The error of `yaml` names `needle` (file:line: key = value: rule ...).
  void has(const std::string& yaml, const std::string& needle) {
    const std::string e = error_of(yaml);
    EXPECT_NE(e.find(needle), std::string::npos) << "got: " << e;
  }
  std::string error_of(const std::string& yaml) {
    const auto p = dir / "scene.yaml";
    std::ofstream(p) << yaml;
    try {
      (void)load_scene(p);
    } catch (const io::InputError& e) {
      const std::string what = e.what();
      EXPECT_EQ(what.rfind(p.string() + ":", 0), 0u) << what;
      return what;
    }
    return "no error";
  }
};

// A scene or grid path that names a FIFO (which would block the read) or a device (which
// never ends) is refused before a byte is read.
TEST_F(BadScene, AFifoOrDeviceIsRefusedBeforeReading) {
  ASSERT_EQ(::mkfifo((dir / "fifo.yaml").c_str(), 0600), 0);
  for (const std::filesystem::path& p : {dir / "fifo.yaml", std::filesystem::path("/dev/zero")}) {
    const std::string e = test::error_of([&] { (void)load_scene(p); });
    EXPECT_EQ(e, p.string() + ": not a regular file (a scene must be one)");
  }
}

TEST_F(BadScene, ErrorsNameLineAndKey) {
  EXPECT_NE(
      error_of("duration_s: 2\nchain:\n  preload: 3\n").find(":3: chain.preload: unknown key"),
      std::string::npos)
      << error_of("duration_s: 2\nchain:\n  preload: 3\n");
  EXPECT_NE(error_of("chain:\n  preload_n: lots\n").find(":2: chain.preload_n: expected a number"),
            std::string::npos);
  EXPECT_NE(
      error_of("chain:\n  preload_n: -5\n").find(":2: chain.preload_n = -5: must be in [0, 1000000]"),
      std::string::npos);
  EXPECT_NE(error_of("chain:\n  cone_limit_deg: 95\n").find(":2: chain.cone_limit_deg = 95: must be in [0.1, 89.9]"),
            std::string::npos);
  EXPECT_NE(error_of("world: {gravity: maybe}\n").find("world.gravity: expected true or false"),
            std::string::npos);
  EXPECT_NE(error_of("base:\n  waypoints:\n    - {t_s: 1, position_m: [0, 0]}\n")
                .find("base.waypoints[0].position_m: expected [x, y, z]"),
            std::string::npos);
  EXPECT_NE(error_of("base:\n  waypoints:\n    - {t_s: 2}\n    - {t_s: 1}\n")
                .find("base: BaseTrajectory: waypoint 1 time 1 s must be later than the one before"),
            std::string::npos);
  EXPECT_NE(error_of("duration_s: [1\n").find("malformed YAML"), std::string::npos);
  // A rule between keys names the key it is about, at that key's line when the file has
  // it, else at the block.
  has("chain:\n  neck_radius_m: 0.02\n", ":2: chain.neck_radius_m = 0.02: must be < ball_radius_m (0.015)");
  has("chain:\n  ball_radius_m: 0.025\n", ":2: chain.pitch_m = 0.045: must be >= 2 * ball_radius_m (balls would overlap)");
  EXPECT_NE(error_of("chain:\n  count: 3.5\n").find(":2: chain.count: expected a whole number"),
            std::string::npos);
  // A whole number beyond its type is refused before it is converted.
  has("tracker:\n  max_points: 18446744073709551616\n", ":2: tracker.max_points = 1.8446744073709552e+19: must be a whole number in "
                      "[0, 1.8446744073709552e+19)");
  EXPECT_NE(error_of("camera:\n  width: 3e9\n").find(":2: camera.width = 3000000000: must be a whole number"),
            std::string::npos);
  EXPECT_EQ(error_of("seed: 9007199254740992\n"), "no error");  // 2^53
  // Issue 59: a camera whose depth PNGs the reader would refuse is refused at its key.
  has("camera:\n  width: 4097\n", ":2: camera.width = 4097: must be in [1, 4096]");
  has("camera:\n  width: 4096\n  height: 2048\n",
      "camera.height = 2048: makes 8388608 pixels with width 4096, more than 4194304");
  // noise.scale scales the file's values after they are checked: a scaled value out of
  // range names the scale.
  has("noise:\n  scale: 60\n  axial: {a_m: 0.002}\n", ":2: noise.scale = 60 makes noise.axial.a_m 0.12, which must be in [0, 0.1]");
  EXPECT_NE(error_of("[1, 2]: 3\n").find(":1: (top level): a key must be a plain name"),
            std::string::npos);
  EXPECT_EQ(error_of("duration_s: 1\n"), "no error");
  // Issue 59: a key's control bytes are escaped, never sent to the terminal: a newline
  // (two lines), an escape that clears the screen, a carriage return that overwrites the
  // message with the attacker's own, and a right-to-left override. A long key is cut.
  has("\"a\\nb\": 1\n", ":1: a\\nb: unknown key");
  has("\"k\\e[2J\\rlinksight: all good\": 1\n", ":1: k\\x1B[2J\\rlinksight: all good: unknown key");
  has("\"x\\u202Ey\": 1\n", ":1: x\\u{202E}y: unknown key");
  for (const std::string& key : std::vector<std::string>{
           "\"a\\nb\": 1\n", "\"\\e[2J\\r\": 1\n", "\"" + std::string(5000, 'k') + "\": 1\n"}) {
    const std::string e = error_of(key);
    EXPECT_TRUE(io::is_printable_line(e)) << e;
    EXPECT_LE(e.size(), 600u) << e;
  }
  // Issue 19: a key given twice (yaml-cpp keeps both; the first would win, silently).
  has("seed: 1\nduration_s: 1\nseed: 2\n", ":3: seed: given twice");
  has("chain:\n  count: 11\n  count: 5\n", ":3: chain.count: given twice");
  // F5: a file past the size limit is refused before it is parsed (10^6 waypoints took
  // 2 GB and 20 s to refuse).
  std::string big = "base:\n  waypoints:\n";
  while (big.size() <= yaml::kMaxFileBytes) big += "    - {t_s: 1, position_m: [0, 0, 0]}\n";
  has(big, "bytes, more than a scene may have (1048576)");
  try {
    (void)load_scene(dir / "missing.yaml");
    FAIL();
  } catch (const io::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.yaml: cannot open scene"), std::string::npos);
  }
}

// Sensor keys: bad values name their key and line.
TEST_F(BadScene, SensorKeysNameLineAndKey) {
  has("camera:\n  fx: 0\n", ":2: camera.fx = 0: must be in [0.001, 100000]");
  has("camera:\n  width: 0\n", "camera.width");
  has("camera:\n  z_min_m: 1.5\n  z_max_m: 1.0\n", ":3: camera.z_max_m = 1: must be > z_min_m (1.5)");
  has("camera:\n  distortion: fisheye\n",
      ":2: camera.distortion: unknown distortion model 'fisheye' (expected none, brown_conrady or "
      "inverse_brown_conrady)");
  has("camera:\n  preset: kinect\n", ":2: camera.preset: unknown camera preset 'kinect' (expected sr300)");
  has("camera:\n  X_WC: [1, 0, 0]\n", "camera.X_WC: expected 16 numbers");
  has("camera:\n  look_at: {eye_m: [0, 0, 1], target_m: [0, 0, 0]}\n",
      "camera.look_at: look_at: view direction is parallel to up");
  has("noise:\n  preset: loud\n",
      ":2: noise.preset: noise preset 'loud': expected off, sr300 or sr300-one-field");
  has("noise:\n  edges: {p_drop: 2}\n", ":2: noise.edges.p_drop = 2: must be in [0, 1]");
  // The reader and validate() share one range: what the file may say, code may set.
  has("noise:\n  axial: {a_m: 0.5}\n", ":2: noise.axial.a_m = 0.5: must be in [0, 0.1]");
  has("noise:\n  axial: {theta_cap_deg: 90}\n", ":2: noise.axial.theta_cap_deg = 90: must be in [0, 89.9]");
  has("noise:\n  axial: {angle_power: 0.1}\n",
      ":2: noise.axial.angle_power = 0.1: must be in [0.5, 4]");
  has("noise:\n  dropouts: {hole_median_px: 5, hole_p90_px: 3}\n",
      ":2: noise.dropouts.hole_p90_px = 3: must be >= hole_median_px (5)");
  has("noise:\n  axial: {sigma: 1}\n", "noise.axial.sigma: unknown key");
  has("noise:\n  axial: {kernel: cauchy}\n",
      ":2: noise.axial.kernel: axial kernel 'cauchy': expected gaussian or matern52");
  has("noise:\n  axial: {correlation_px: 21}\n", ":2: noise.axial.correlation_px = 21: must be in [0, 20]");
  has("noise:\n  axial: {kernel: matern52, correlation_px: 2}\n",
      "noise.axial.correlation_px = 2: must be 0 or >= 3 with kernel matern52");
  has("occluders:\n  - shape: cone\n", ":2: occluders[0].shape: unknown shape 'cone' (expected box, cylinder, sphere or mesh)");
  has("occluders:\n  - shape: mesh\n    mesh: nowhere/hand.obj\n",
      ":3: occluders[0].mesh: " + (dir / "nowhere/hand.obj").string() + ": mesh file not found");
  has("occluders:\n  - shape: box\n    mesh: a.obj\n", "occluders[0].mesh: only for shape: mesh");
  has("background:\n  objects:\n    - {shape: box, half_extents_m: [0.1, 0, 0.1]}\n",
      ":3: background.objects[0].half_extents_m = 0: must all be > 0");
  // List items are read through their structs' field lists too: their rules are the
  // structs' validate(), at the item's path and line.
  has("occluders:\n  - {from_s: -1}\n", ":2: occluders[0].from_s = -1: must be in [0, 1000000]");
  has("occluders:\n  - {reflectance: 11}\n", ":2: occluders[0].reflectance = 11: must be in [0, 10]");
  has("actions:\n  forces:\n    - {component: 11}\n",
      ":3: actions.forces[0].component = 11: must be < the chain's count (11)");
  has("actions:\n  forces:\n    - {t_start_s: 2, t_end_s: 1}\n",
      ":3: actions.forces[0].t_end_s = 1: must be >= t_start_s (2)");
  has("actions:\n  gravity:\n    - {t_s: 1, on: sometimes}\n",
      ":3: actions.gravity[0].on: expected true or false");
  has("base:\n  sweeps:\n    - {axis: [0, 0, 0]}\n", ":3: base.sweeps[0].axis = [...]: must not be zero");
  has("base:\n  sweeps:\n    - {amplitude_deg: 200}\n",
      ":3: base.sweeps[0].amplitude_deg = 200: must be in [-180, 180]");
  has("actions:\n  obstacles:\n    - {half_extents_m: [1, 1, -1]}\n",
      ":3: actions.obstacles[0].half_extents_m = -1: must all be > 0");
  has("segmentation:\n  mode: colour\n", "segmentation.mode: unknown segmentation mode 'colour' (expected truth or depth)");
  has("segmentation:\n  crop_min_m: [0, 0, 0]\n", "give crop_min_m and crop_max_m together");
}

TEST(Scene, SensorKeysReachTheStructs) {
  const Scene s = load_scene(kScenes / "occluder_pass.yaml");
  EXPECT_EQ(s.occluders.size(), 2u);
  EXPECT_EQ(s.occluders[0].shape.kind, Shape::Kind::mesh);
  EXPECT_TRUE(std::filesystem::exists(s.occluders[0].shape.mesh));
  EXPECT_EQ(s.background.size(), 3u);  // table, wall, mug
  EXPECT_NEAR(s.camera.X_WC.translation().y(), -0.6, 1e-12);
  // The table's top face is at height_m.
  EXPECT_NEAR(s.background[0].X_WO.translation().z() + s.background[0].shape.half_extents.z(),
              0.30, 1e-12);
  const Scene c = load_scene(kScenes / "clutter.yaml");
  EXPECT_EQ(c.segmentation.mode, ExtractParams::Mode::depth);
  ASSERT_TRUE(c.segmentation.crop_C.has_value());
  EXPECT_DOUBLE_EQ(c.segmentation.crop_C->max().z(), 0.75);
  auto sensor = make_sensor(c);
  EXPECT_EQ(sensor->params().noise.shadow.baseline, NoiseParams::sr300().shadow.baseline);
}

// --print-scene: every shipped scene, printed and read back, prints the same again (so
// every field of every block reads back to the same bits), from another folder too.
TEST_F(BadScene, ResolvedSceneReadsBackToTheSameScene) {
  for (const auto& entry : std::filesystem::directory_iterator(kScenes)) {
    if (entry.path().extension() != ".yaml") continue;
    const std::vector<std::string> set = {"noise.scale=1.5", "tracker.iterations=7"};
    const std::string once = resolved_scene_yaml(entry.path(), set);
    const auto copy = dir / ("resolved_" + entry.path().filename().string());
    std::ofstream(copy) << once;
    const std::string twice = resolved_scene_yaml(copy);
    // The two differ in their first comment line only (the file and the --set given).
    EXPECT_EQ(once.substr(once.find('\n')), twice.substr(twice.find('\n'))) << entry.path();
    const Scene a = load_scene(entry.path(), set), b = load_scene(copy);
    EXPECT_EQ(a.noise.axial.a, b.noise.axial.a) << entry.path();
    EXPECT_EQ(a.noise.dropouts.max_incidence, b.noise.dropouts.max_incidence);
    EXPECT_EQ(a.chain.cone_limit, b.chain.cone_limit);
    EXPECT_TRUE(a.camera.X_WC.matrix() == b.camera.X_WC.matrix()) << entry.path();
    EXPECT_EQ(a.tracker.iterations, 7);
    EXPECT_EQ(b.tracker.iterations, 7);
    EXPECT_EQ(a.occluders.size(), b.occluders.size());
    EXPECT_EQ(a.background.size(), b.background.size());
  }
}

// calibrate-noise's block is NoiseParams' field list: read back, the same parameters.
TEST_F(BadScene, NoiseBlockReadsBackToTheSameNoise) {
  NoiseParams n = NoiseParams::sr300();
  n.axial.a = 1.0 / 30000;
  n.axial.theta_cap = 0.123456789;
  n.axial.angle_power = 1.375;
  n.axial.kernel = AxialKernel::matern52;
  n.axial.correlation_px = 4.5;  // a Matern's range is at least 3 px
  n.axial.correlation_cols_px = 5.5;
  n.edges.enabled = false;
  n.quantize = false;
  const auto p = dir / "noise.yaml";
  std::ofstream(p) << noise_yaml(n);
  const NoiseParams m = load_scene(p).noise;
  EXPECT_EQ(m.axial.a, n.axial.a);
  EXPECT_EQ(m.axial.theta_cap, n.axial.theta_cap);
  EXPECT_EQ(m.axial.angle_power, n.axial.angle_power);
  EXPECT_EQ(m.axial.correlation_px, n.axial.correlation_px);
  EXPECT_EQ(m.axial.kernel, AxialKernel::matern52);
  EXPECT_FALSE(m.edges.enabled);
  EXPECT_FALSE(m.quantize);
  EXPECT_EQ(m.dropouts.hole_p90_px, n.dropouts.hole_p90_px);
  EXPECT_EQ(noise_yaml(m), noise_yaml(n));
}

// Defaults that depend on other keys: a force without t_end_s is one instant; an
// occluder without from_s or to_s is there from the start or to the end.
TEST_F(BadScene, ListItemDefaultsThatDependOnOtherKeys) {
  const auto p = dir / "scene.yaml";
  std::ofstream(p) << "actions:\n  forces:\n    - {component: 3, t_start_s: 1.5}\n"
                   << "occluders:\n  - {to_s: 2}\n  - {from_s: 1}\n  - {}\n";
  const Scene s = load_scene(p);
  ASSERT_EQ(s.forces.size(), 1u);
  EXPECT_EQ(s.forces[0].t_start, 1.5);
  EXPECT_EQ(s.forces[0].t_end, 1.5);
  ASSERT_EQ(s.occluders.size(), 3u);
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_EQ(s.occluders[0].from_s, -inf);
  EXPECT_EQ(s.occluders[0].to_s, 2.0);
  EXPECT_EQ(s.occluders[1].from_s, 1.0);
  EXPECT_EQ(s.occluders[1].to_s, inf);
  EXPECT_EQ(s.occluders[2].from_s, -inf);
  EXPECT_EQ(s.occluders[2].to_s, inf);
  has("occluders:\n  - {to_s: 0}\n", ":2: occluders[0].to_s = 0: must be in (0, 1000000]");  // never there
}

// Every struct lists each key once.
struct KeyRecorder {
  std::vector<std::string> keys;
  template <class T, class... R>
  void operator()(const char* key, T&, R&&...) {
    keys.emplace_back(key);
  }
};
template <class T>
void expect_unique_keys(T x, const char* name) {
  KeyRecorder r;
  x.fields(r);
  const std::set<std::string> unique(r.keys.begin(), r.keys.end());
  EXPECT_EQ(unique.size(), r.keys.size()) << name;
  EXPECT_FALSE(r.keys.empty()) << name;
}
TEST(SceneFields, EveryStructListsEachKeyOnce) {
  expect_unique_keys(CameraParams{}, "camera");
  expect_unique_keys(NoiseParams{}, "noise");
  expect_unique_keys(AxialNoise{}, "noise.axial");
  expect_unique_keys(Dropouts{}, "noise.dropouts");
  expect_unique_keys(EdgeEffects{}, "noise.edges");
  expect_unique_keys(ExtractParams{}, "segmentation");
  expect_unique_keys(ChainParams{}, "chain");
  expect_unique_keys(WorldParams{}, "world");
  expect_unique_keys(ScreenOcclusion{}, "occlusion");
  expect_unique_keys(TrackerParams{}, "tracker");
  expect_unique_keys(Occluder{}, "occluders[]");
  expect_unique_keys(BackgroundObject{}, "background.objects[]");
  expect_unique_keys(Sweep{}, "sweeps[]");
  expect_unique_keys(ForceAction{}, "actions.forces[]");
  expect_unique_keys(PusherParams{}, "actions.pushers[]");
}

TEST_F(BadScene, NoiseOverridesStartFromThePreset) {
  const auto p = dir / "scene.yaml";
  std::ofstream(p) << "noise:\n  preset: off\n  axial: {a_m: 0.001}\n"
                   << "camera:\n  X_WC: [1, 0, 0, 0.1,  0, 1, 0, 0.2,  0, 0, 1, 0.3,  0, 0, 0, 1]\n";
  const Scene s = load_scene(p);
  EXPECT_TRUE(s.noise.axial.enabled);  // a block switches its term on unless it says not
  EXPECT_DOUBLE_EQ(s.noise.axial.a, 0.001);
  EXPECT_FALSE(s.noise.shadow.enabled);
  EXPECT_FALSE(s.noise.edges.enabled);
  EXPECT_DOUBLE_EQ(s.camera.X_WC.translation().z(), 0.3);
}

}  // namespace
}  // namespace linksight::sim
