#include <gtest/gtest.h>

#include <fstream>

#define STB_IMAGE_WRITE_IMPLEMENTATION
#include <stb/stb_image_write.h>

#include "linksight/io/depth_png.hpp"
#include "linksight/io/error.hpp"
#include "test_support.hpp"

namespace linksight::io {
namespace {

const std::filesystem::path kData = LINKSIGHT_TEST_DATA_DIR;

class DepthPng : public ::testing::Test {
 protected:
  std::filesystem::path dir =
      test::scratch_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
};

TEST_F(DepthPng, WriteReadRoundTripKeepsEveryBit) {
  DepthImage img;
  img.width = 300;  // rows over 64 KiB force several stored deflate blocks
  img.height = 200;
  for (int i = 0; i < img.width * img.height; ++i)
    img.data.push_back(static_cast<std::uint16_t>(i * 2654435761u >> 16));
  img.data[0] = 0;
  img.data[1] = 65535;
  write_depth_png(dir / "d.png", img);
  const DepthImage r = read_depth_png(dir / "d.png");
  EXPECT_EQ(r.width, 300);
  EXPECT_EQ(r.height, 200);
  EXPECT_EQ(r.data, img.data);
}

TEST_F(DepthPng, RejectsEightBitAndColour) {
  std::vector<unsigned char> gray(16 * 8, 100);
  stbi_write_png((dir / "g8.png").c_str(), 16, 8, 1, gray.data(), 16);
  try {
    (void)read_depth_png(dir / "g8.png");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("g8.png: depth PNG must be 16-bit"), std::string::npos)
        << e.what();
  }
  std::ofstream(dir / "junk.png") << "not a png";
  EXPECT_THROW((void)read_depth_png(dir / "junk.png"), InputError);
}

TEST_F(DepthPng, PlaneBackProjectsToItsDepth) {
  Intrinsics k;
  k.width = 64;
  k.height = 48;
  k.cx = 31.5;
  k.cy = 23.5;
  DepthImage img{64, 48, std::vector<std::uint16_t>(64 * 48, 4000)};  // 0.5 m
  img.data[5] = 0;                                                    // a hole
  const Cloud c = depth_to_cloud(img, k);
  ASSERT_EQ(c.size(), 64u * 48 - 1);
  for (std::size_t i = 0; i < c.size(); ++i) EXPECT_FLOAT_EQ(c.xyz[3 * i + 2], 0.5f);
  // Pixel (0,0) at z = 0.5 m: x = (0 - cx) / fx * z.
  EXPECT_NEAR(c.xyz[0], -31.5 / k.fx * 0.5, 1e-7);

  DepthToCloudOptions range;
  range.max_depth = 0.4;
  EXPECT_TRUE(depth_to_cloud(img, k, range).empty());
  DepthToCloudOptions crop;
  crop.crop_C = Eigen::AlignedBox3d(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 1, 1));
  const Cloud cropped = depth_to_cloud(img, k, crop);
  EXPECT_GT(cropped.size(), 0u);
  EXPECT_LT(cropped.size(), c.size() / 3);
  for (std::size_t i = 0; i < cropped.size(); ++i) EXPECT_GE(cropped.xyz[3 * i], 0.f);

  Intrinsics wrong = k;
  wrong.width = 640;
  try {
    (void)depth_to_cloud(img, wrong);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "image is 64x48 but intrinsics say 640x48");
  }
  DepthToCloudOptions bad;
  bad.min_depth = 2;
  bad.max_depth = 1;
  EXPECT_THROW(bad.validate(), std::invalid_argument);
}

// A real SR305 frame: a person at 0.5–0.9 m, background out of range.
TEST(DepthPngReal, Sr305FrameGivesAPlausibleCloud) {
  const DepthImage img = read_depth_png(kData / "sr305/100.png");
  ASSERT_EQ(img.width, 640);
  ASSERT_EQ(img.height, 480);
  const Intrinsics k = read_intrinsics(kData / "sr305/intrinsics.json");
  const Cloud c = depth_to_cloud(img, k);
  EXPECT_GT(c.size(), 20000u);
  std::size_t near = 0;
  for (std::size_t i = 0; i < c.size(); ++i) {
    const float z = c.xyz[3 * i + 2];
    EXPECT_GT(z, 0.1f);
    EXPECT_LT(z, 1.6f);
    near += z > 0.45f && z < 0.95f;
  }
  EXPECT_GT(static_cast<double>(near) / c.size(), 0.8);
}

}  // namespace
}  // namespace linksight::io
