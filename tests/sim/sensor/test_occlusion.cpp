// The generated occluder (scene key `occlusion`, sim/occlusion) and an occluder's time
// window: it hides the fraction it is sized for, at the middle or the tip, only while
// present, carried with a moving base; bad keys are named.
#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "linksight/io/error.hpp"
#include "linksight/sim/episode.hpp"
#include "linksight/sim/occlusion.hpp"
#include "linksight/sim/scene.hpp"
#include "test_support.hpp"

namespace linksight::sim {
namespace {

// The box is sized on the link's length seen from the camera; balls are round and the
// projector shadow adds a sliver, so the hidden pixel fraction is near, not equal.
constexpr double kFractionTol = 0.03;

std::filesystem::path write_scene(const std::string& name, const std::string& yaml) {
  const auto dir = test::scratch_dir(name);
  const auto p = dir / "scene.yaml";
  std::ofstream(p) << yaml;
  return p;
}

// The occluded fraction of the link at every frame of a scene (no tracker work needed
// beyond the episode's own).
std::vector<double> occluded_fractions(const Scene& scene) {
  EpisodeOptions o;
  o.threads = 1;
  Episode e(scene, o);
  std::vector<double> f;
  while (e.done() < e.frames()) f.push_back(e.step().image->link_occluded_fraction);
  return f;
}

const std::string kStill = R"(duration_s: 0.4
camera: {fps: 10}
noise: {preset: off}
base: {waypoints: [{t_s: 0, position_m: [0, 0, 0.5]}]}
occlusion: {from_s: 0.1, to_s: 0.3}
)";

TEST(Occlusion, HidesItsFractionOnlyInsideItsWindow) {
  const auto file = write_scene("occlusion_window", kStill);
  for (const std::string at : {"middle", "tip"}) {
    for (double fraction : {0.1, 0.3, 0.5}) {
      SCOPED_TRACE(at + " " + std::to_string(fraction));
      const Scene s = load_scene(file, {"occlusion.at=" + at,
                                        "occlusion.fraction=" + std::to_string(fraction)});
      ASSERT_EQ(s.occluders.size(), 1u);
      const std::vector<double> f = occluded_fractions(s);  // t = 0, 0.1, 0.2, 0.3, 0.4
      ASSERT_EQ(f.size(), 5u);
      EXPECT_EQ(f[0], 0.0);
      EXPECT_NEAR(f[1], fraction, kFractionTol);
      EXPECT_NEAR(f[2], fraction, kFractionTol);
      EXPECT_EQ(f[3], 0.0);  // gone at to_s
      EXPECT_EQ(f[4], 0.0);
    }
  }
  EXPECT_TRUE(load_scene(file).occluders.empty());  // fraction 0: no occluder at all
}

TEST(Occlusion, MiddleAndTipHideDifferentBalls) {
  const auto file = write_scene("occlusion_where", kStill);
  auto hidden = [&](const std::string& at) {
    Scene s = load_scene(file, {"occlusion.at=" + at, "occlusion.fraction=0.2"});
    EpisodeOptions o;
    o.threads = 1;
    Episode e(s, o);
    (void)e.step();
    const DepthFrame& img = *e.step().image;  // t = 0.1: present
    std::vector<int> balls;
    for (int c = 0; c < s.chain.geometry.count; ++c)
      if (img.occluded_fraction[c] > 0.5) balls.push_back(c);
    return balls;
  };
  // The silhouette runs from ball 0's back (-15 mm) to the last neck's end (487 mm): its
  // middle, 236 mm, is between balls 5 (225 mm) and 6 (270 mm), and 20% is 100 mm.
  EXPECT_EQ(hidden("middle"), (std::vector<int>{5, 6}));
  const std::vector<int> tip = hidden("tip");
  ASSERT_FALSE(tip.empty());
  EXPECT_EQ(tip.back(), 10);
  EXPECT_GE(tip.front(), 8);
}

TEST(Occlusion, FollowsTheBaseSoTheHiddenPartStays) {
  const auto file = write_scene("occlusion_follow", R"(duration_s: 1.0
camera: {fps: 10}
noise: {preset: off}
base:
  waypoints:
    - {t_s: 0.0, position_m: [0.0, 0.0, 0.5]}
    - {t_s: 1.0, position_m: [0.03, 0.0, 0.6], rpy_deg: [0, 0, 10]}
occlusion: {fraction: 0.3, from_s: 0.2, to_s: 1.0}
)");
  const std::vector<double> carried = occluded_fractions(load_scene(file));
  const std::vector<double> left =
      occluded_fractions(load_scene(file, {"occlusion.follow_base=false"}));
  for (int f = 2; f < 10; ++f) EXPECT_NEAR(carried[f], 0.3, kFractionTol) << "frame " << f;
  // Left where it appeared, the board loses the link as the base lifts it 10 cm.
  EXPECT_LT(left[9], 0.3 - 3 * kFractionTol);
}

TEST(Occlusion, BadKeysAreNamed) {
  auto error_of = [](const std::string& yaml) {
    const auto file = write_scene("occlusion_bad", yaml);
    try {
      (void)load_scene(file);
    } catch (const io::InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(error_of("occlusion: {fraction: 1.2}\n").find(":1: occlusion.fraction = 1.2: must be in [0, 0.95]"),
            std::string::npos);
  EXPECT_NE(error_of("occlusion: {at: base}\n").find("occlusion.at: unknown occlusion site 'base' (expected middle or tip)"),
            std::string::npos);
  EXPECT_NE(error_of("occlusion: {from_s: 2, to_s: 1}\n").find("occlusion.to_s"), std::string::npos);
  EXPECT_NE(error_of("occlusion: {size: 3}\n").find("occlusion.size: unknown key"), std::string::npos);
  // A camera looking away from the link: the board cannot be placed.
  EXPECT_NE(error_of("camera:\n  look_at: {eye_m: [0.25, -0.6, 0.6], target_m: [0.25, -1.6, 0.6]}\n"
                     "occlusion: {fraction: 0.2}\n")
                .find(":3: occlusion: the link at from_s"),
            std::string::npos);
  // A board inside the balls would hide less than asked.
  EXPECT_NE(error_of("occlusion: {fraction: 0.2, gap_m: 0.01}\n")
                .find(":1: occlusion.gap_m = 0.01: must be >= 0.022 m, so the board clears the balls"),
            std::string::npos)
      << error_of("occlusion: {fraction: 0.2, gap_m: 0.01}\n");
  EXPECT_NE(error_of("duration_s: 1\nocclusion: {fraction: 0.2, from_s: 1.5, to_s: 2}\n")
                .find(":2: occlusion.from_s = 1.5: must be < duration_s (1)"),
            std::string::npos);
  EXPECT_NE(error_of("occluders:\n  - {from_s: 2, to_s: 1}\n")
                .find("occluders[0].to_s = 1: must be > from_s (2)"),
            std::string::npos);
  EXPECT_EQ(error_of("occlusion: {fraction: 0.2, at: tip, gap_m: 0.1, height_m: 0.05}\n"), "no error");
}

TEST(Occlusion, SensorRefusesAnEmptyWindow) {
  Occluder o;
  o.from_s = 2.0;
  o.to_s = 1.0;
  SensorParams p;
  const std::string e = test::error_of<std::invalid_argument>(
      [&] { Sensor s(p, ComponentGeometry{}, {Occluder{}, o}); });
  EXPECT_NE(e.find("occluder 1: occluder.to_s = 1: must be > from_s (2)"), std::string::npos) << e;
}

TEST(Occlusion, ParamsValidateNamesTheField) {
  ScreenOcclusion o;
  o.fraction = -0.1;
  EXPECT_THROW(o.validate(), std::invalid_argument);
  o = {};
  o.to_s = o.from_s;
  const std::string e2 = test::error_of<std::invalid_argument>([&] { o.validate(); });
  EXPECT_NE(e2.find("occlusion.to_s"), std::string::npos) << e2;
}

}  // namespace
}  // namespace linksight::sim
