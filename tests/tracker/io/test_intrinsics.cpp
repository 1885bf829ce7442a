#include <gtest/gtest.h>

#include <fstream>

#include "linksight/io/error.hpp"
#include "linksight/io/intrinsics.hpp"
#include "test_support.hpp"

namespace linksight::io {
namespace {

class IntrinsicsFile : public ::testing::Test {
 protected:
  std::filesystem::path dir =
      test::scratch_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
  std::string error_of(const std::string& json) {
    const auto p = dir / "intrinsics.json";
    std::ofstream(p) << json;
    try {
      (void)read_intrinsics(p);
    } catch (const InputError& e) {
      const std::string what = e.what();
      EXPECT_EQ(what.rfind(p.string() + ": ", 0), 0u) << what;
      return what;
    }
    return "no error";
  }
};

const char* kGood =
    R"({"width": 640, "height": 480, "fx": 476.007, "fy": 476.007, "cx": 313.683, "cy": 242.755, "depth_scale": 0.000125})";

TEST_F(IntrinsicsFile, ReadsTheSr305File) {
  const Intrinsics k =
      read_intrinsics(std::filesystem::path(LINKSIGHT_TEST_DATA_DIR) / "sr305/intrinsics.json");
  EXPECT_EQ(k.width, 640);
  EXPECT_DOUBLE_EQ(k.fx, 476.007);
  EXPECT_DOUBLE_EQ(k.depth_scale, 0.000125);
  EXPECT_EQ(k.model, Distortion::none);
}

TEST_F(IntrinsicsFile, WriteReadRoundTripWithDistortion) {
  Intrinsics k;
  k.model = Distortion::inverse_brown_conrady;
  k.coeffs = {0.1, -0.05, 0.001, -0.002, 0.01};
  write_intrinsics(dir / "k.json", k);
  const Intrinsics r = read_intrinsics(dir / "k.json");
  EXPECT_EQ(r.model, k.model);
  EXPECT_EQ(r.coeffs, k.coeffs);
  EXPECT_EQ(r.cx, k.cx);
}

TEST_F(IntrinsicsFile, Errors) {
  EXPECT_EQ(error_of(kGood), "no error");
  EXPECT_NE(error_of("{\"width\": 640,").find("malformed JSON"), std::string::npos);
  EXPECT_NE(error_of(R"({"width": 640})").find("missing key 'height'"), std::string::npos);
  EXPECT_NE(error_of(R"({"width": "640", "height": 480})").find("key 'width' must be a number"),
            std::string::npos);
  EXPECT_NE(
      error_of(R"({"width": 640.5, "height": 480})").find("key 'width' must be a positive integer"),
      std::string::npos);
  EXPECT_NE(error_of(R"({"widht": 640})").find("unknown key 'widht'"), std::string::npos);
  EXPECT_NE(error_of(R"([1, 2])").find("expected a JSON object"), std::string::npos);
  std::string neg = kGood;
  neg.replace(neg.find("476.007"), 7, "-1");
  EXPECT_NE(error_of(neg).find("intrinsics.fx"), std::string::npos);
  // Issue 59: a focal length of 1e308 px (a field of view of 10^-305 degrees) is refused,
  // as is a depth unit of a kilometre.
  std::string huge = kGood;
  huge.replace(huge.find("476.007"), 7, "1e308");
  EXPECT_NE(error_of(huge).find("intrinsics.fx = 1e+308: must be in (0, 235000] px (a field of "
                                "view of 1 degree or more)"),
            std::string::npos)
      << error_of(huge);
  for (const auto& [value, key] :
       {std::pair{"\"fy\": 1e6", "intrinsics.fy = 1000000: must be in"},
        std::pair{"\"depth_scale\": 1000", "intrinsics.depth_scale = 1000"}}) {
    std::string s = kGood;
    const std::string k = std::string(value).substr(0, std::string(value).find(':') + 1);
    const std::size_t at = s.find(k);
    ASSERT_NE(at, std::string::npos) << k;
    s.replace(at, s.find_first_of(",}", at) - at, value);
    EXPECT_NE(error_of(s).find(key), std::string::npos) << error_of(s);
  }
  // Issue 59: a value nested 100,000 deep is refused before it is parsed, and a key's
  // control bytes are escaped.
  EXPECT_NE(error_of("{\"width\": " + std::string(100000, '['))
                .find("JSON nested deeper than 64 levels (byte 73)"),
            std::string::npos);
  EXPECT_NE(error_of("{\"wid\\u001bth\\r\": 640}").find("unknown key 'wid\\x1Bth\\r'"),
            std::string::npos)
      << error_of("{\"wid\\u001bth\\r\": 640}");
  std::string model = kGood;
  model.insert(model.size() - 1, R"(, "model": "fisheye", "coeffs": [0,0,0,0,0])");
  EXPECT_NE(error_of(model).find("key 'model': unknown distortion model 'fisheye' (expected none, brown_conrady or inverse_brown_conrady)"), std::string::npos);
  std::string coeffs = kGood;
  coeffs.insert(coeffs.size() - 1, R"(, "model": "brown_conrady", "coeffs": [0,0,0])");
  EXPECT_NE(error_of(coeffs).find("array of 5 numbers"), std::string::npos);
  EXPECT_NE(error_of("").find("malformed JSON"), std::string::npos);
  try {
    (void)read_intrinsics(dir / "missing.json");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.json: cannot open"), std::string::npos);
  }
}

TEST(Intrinsics, ProjectDeprojectRoundTripForEveryModel) {
  for (Distortion model :
       {Distortion::none, Distortion::brown_conrady, Distortion::inverse_brown_conrady}) {
    Intrinsics k;
    k.model = model;
    k.coeffs = {0.12, -0.3, 0.002, -0.001, 0.1};
    for (double u : {0.0, 100.5, 310.0, 639.0}) {
      for (double v : {0.0, 245.0, 479.0}) {
        const Eigen::Vector3d p = k.deproject(u, v, 0.7);
        EXPECT_DOUBLE_EQ(p.z(), 0.7);
        const Eigen::Vector2d back = k.project(p);
        EXPECT_NEAR(back.x(), u, 1e-6) << static_cast<int>(model);
        EXPECT_NEAR(back.y(), v, 1e-6) << static_cast<int>(model);
      }
    }
  }
  // Strong distortion, corner pixel: Newton still inverts it.
  Intrinsics strong;
  strong.model = Distortion::brown_conrady;
  strong.coeffs = {0.5, 0.0, 0.0, 0.0, 0.0};
  EXPECT_NEAR(strong.project(strong.deproject(0.0, 0.0, 1.0)).x(), 0.0, 1e-6);
  EXPECT_NEAR(strong.project(strong.deproject(0.0, 0.0, 1.0)).y(), 0.0, 1e-6);
  Intrinsics k;  // the principal point looks straight ahead
  EXPECT_TRUE(k.deproject(k.cx, k.cy, 0.5).isApprox(Eigen::Vector3d(0, 0, 0.5)));
  // Distortion moves corner pixels.
  Intrinsics d = k;
  d.model = Distortion::inverse_brown_conrady;
  d.coeffs = {0.1, 0, 0, 0, 0};
  EXPECT_GT((d.deproject(0, 0, 1) - k.deproject(0, 0, 1)).norm(), 0.01);
}

// Known values, worked by hand from the Brown-Conrady formula (OpenCV/RealSense order
// k1, k2, p1, p2, k3): x = 0.3, y = -0.2, k1 = 0.1, k2 = 0.01, p1 = 0.001, p2 = 0.002.
// r2 = 0.13, radial = 1.013169; xd = 0.3039507 - 0.00012 + 0.00062 = 0.3044507,
// yd = -0.2026338 - 0.00024 + 0.00021 = -0.2026638.
TEST(Intrinsics, BrownConradyKnownValues) {
  Intrinsics k;
  k.fx = 500;
  k.fy = 400;
  k.cx = 320;
  k.cy = 240;
  k.model = Distortion::brown_conrady;
  k.coeffs = {0.1, 0.01, 0.001, 0.002, 0.0};
  const Eigen::Vector2d px = k.project(Eigen::Vector3d(0.6, -0.4, 2.0));  // x = 0.3, y = -0.2
  EXPECT_NEAR(px.x(), 320 + 500 * 0.3044507, 1e-9);
  EXPECT_NEAR(px.y(), 240 + 400 * -0.2026638, 1e-9);
  // The inverse model applies the same polynomial when deprojecting (RealSense SR300 depth).
  Intrinsics inv = k;
  inv.model = Distortion::inverse_brown_conrady;
  const Eigen::Vector3d p = inv.deproject(320 + 500 * 0.3, 240 + 400 * -0.2, 2.0);
  EXPECT_NEAR(p.x(), 2.0 * 0.3044507, 1e-9);
  EXPECT_NEAR(p.y(), 2.0 * -0.2026638, 1e-9);
}

}  // namespace
}  // namespace linksight::io
