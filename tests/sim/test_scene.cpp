// Scene files: the shipped physics scenes do what their comments say; bad files name
// the file, the line and the key.
#include <gtest/gtest.h>

#include <fstream>

#include "linksight/io/error.hpp"
#include "linksight/sim/scene.hpp"
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

TEST_F(BadScene, ErrorsNameLineAndKey) {
  EXPECT_NE(
      error_of("duration_s: 2\nchain:\n  preload: 3\n").find(":3: chain.preload: unknown key"),
      std::string::npos)
      << error_of("duration_s: 2\nchain:\n  preload: 3\n");
  EXPECT_NE(error_of("chain:\n  preload_n: lots\n").find(":2: chain.preload_n: expected a number"),
            std::string::npos);
  EXPECT_NE(
      error_of("chain:\n  preload_n: -5\n").find("chain.preload_n: -5.000000 is out of range"),
      std::string::npos);
  EXPECT_NE(error_of("chain:\n  cone_limit_deg: 95\n").find("chain.cone_limit_deg"),
            std::string::npos);
  EXPECT_NE(error_of("world: {gravity: maybe}\n").find("world.gravity: expected true or false"),
            std::string::npos);
  EXPECT_NE(error_of("base:\n  waypoints:\n    - {t_s: 1, position_m: [0, 0]}\n")
                .find("base.waypoints[0].position_m: expected [x, y, z]"),
            std::string::npos);
  EXPECT_NE(error_of("base:\n  waypoints:\n    - {t_s: 2}\n    - {t_s: 1}\n")
                .find("must be finite and increasing"),
            std::string::npos);
  EXPECT_NE(error_of("duration_s: [1\n").find("malformed YAML"), std::string::npos);
  EXPECT_NE(error_of("chain:\n  ball_radius_m: 0.03\n").find("ChainParams"),
            std::string::npos);  // pitch < 2r
  EXPECT_EQ(error_of("duration_s: 1\n"), "no error");
  try {
    (void)load_scene(dir / "missing.yaml");
    FAIL();
  } catch (const io::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.yaml: cannot open scene"), std::string::npos);
  }
}

}  // namespace
}  // namespace linksight::sim
