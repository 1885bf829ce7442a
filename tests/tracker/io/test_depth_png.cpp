#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <iterator>

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

// stb_image checks neither CRCs nor Adler-32, so the round trip above cannot catch a bad
// checksum. These bytes were verified independently (Python's zlib: every chunk CRC,
// decompression with Adler-32 check, raw rows 00 1234 abcd).
TEST_F(DepthPng, WriterMatchesIndependentlyVerifiedBytes) {
  write_depth_png(dir / "g.png", DepthImage{2, 1, {0x1234, 0xABCD}});
  std::ifstream in(dir / "g.png", std::ios::binary);
  const std::vector<unsigned char> got((std::istreambuf_iterator<char>(in)), {});
  const std::vector<unsigned char> expected = {
      0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44,
      0x52, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x01, 0x10, 0x00, 0x00, 0x00, 0x00, 0x81,
      0xd9, 0xfc, 0x15, 0x00, 0x00, 0x00, 0x10, 0x49, 0x44, 0x41, 0x54, 0x78, 0x01, 0x01, 0x05,
      0x00, 0xfa, 0xff, 0x00, 0x12, 0x34, 0xab, 0xcd, 0x03, 0x0c, 0x01, 0xbf, 0x4c, 0x32, 0xd4,
      0xc3, 0x00, 0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82};
  EXPECT_EQ(got, expected);
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

// A chunk that declares more bytes than the file holds is refused before decoding:
// stb_image sized its buffer by the declared length first (fuzz_depth_png: a 117-byte file
// whose IDAT declares 1.2 GB took 2 GiB). The valid file's chunks all fit.
TEST_F(DepthPng, AChunkLongerThanTheFileIsRefusedBeforeDecoding) {
  write_depth_png(dir / "ok.png", DepthImage{2, 1, {0x1234, 0xABCD}});
  std::ifstream in(dir / "ok.png", std::ios::binary);
  std::vector<char> bytes((std::istreambuf_iterator<char>(in)), {});
  EXPECT_EQ(read_depth_png(dir / "ok.png").data, (std::vector<std::uint16_t>{0x1234, 0xABCD}));
  // The IDAT chunk (at byte 33) now declares 0x48000000 bytes.
  bytes[33] = 0x48;
  std::ofstream(dir / "long.png", std::ios::binary).write(bytes.data(),
                                                          static_cast<std::streamsize>(bytes.size()));
  const std::string e = test::error_of([&] { (void)read_depth_png(dir / "long.png"); });
  EXPECT_NE(e.find("long.png: not a readable PNG (the chunk at byte 33 declares 1207959568 "
                   "bytes, the file has 32 after its header)"),
            std::string::npos)
      << e;
}

// A valid PNG whose first IDAT chunk is empty: stb_image copies it into a buffer it has
// not allocated yet (memcpy to NULL, undefined behaviour under UBSan). Refused before stb
// sees it; an empty IDAT after data is harmless and read.
TEST_F(DepthPng, AnEmptyFirstIdatIsRefusedBeforeDecoding) {
  write_depth_png(dir / "ok.png", DepthImage{2, 1, {0x1234, 0xABCD}});
  std::ifstream in(dir / "ok.png", std::ios::binary);
  const std::vector<char> bytes((std::istreambuf_iterator<char>(in)), {});
  const char empty_idat[] = {0, 0, 0, 0, 'I', 'D', 'A', 'T', '\x35', '\xAF', '\x06', '\x1E'};
  const auto write_with_empty_idat_at = [&](const char* name, std::size_t at) {
    std::vector<char> b = bytes;
    b.insert(b.begin() + static_cast<std::ptrdiff_t>(at), std::begin(empty_idat),
             std::end(empty_idat));
    std::ofstream(dir / name, std::ios::binary)
        .write(b.data(), static_cast<std::streamsize>(b.size()));
  };
  write_with_empty_idat_at("first.png", 33);  // before the data's IDAT
  EXPECT_EQ(test::error_of([&] { (void)read_depth_png(dir / "first.png"); }),
            (dir / "first.png").string() +
                ": not a readable PNG (its first IDAT chunk, at byte 33, is empty)");
  write_with_empty_idat_at("after.png", bytes.size() - 12);  // before IEND
  EXPECT_EQ(read_depth_png(dir / "after.png").data, (std::vector<std::uint16_t>{0x1234, 0xABCD}));
}

// Image data that inflates to more than its header's pixels hold is refused before stb
// sees it: stb_image grew its buffer for as long as the stream went on (a 1x1 header over
// 10 KB of compressed zeros inflating to 10 MB, or over a few MB to gigabytes).
TEST_F(DepthPng, ImageDataLongerThanItsPixelsIsRefusedBeforeDecoding) {
  // A stored (uncompressed) deflate stream of `raw` bytes, as write_depth_png writes.
  const auto png_of = [&](const char* name, std::uint32_t w, std::uint32_t h, std::size_t raw) {
    std::vector<unsigned char> data(raw, 0);
    std::vector<unsigned char> z = {0x78, 0x01};
    for (std::size_t pos = 0; pos < raw;) {
      const std::size_t len = std::min<std::size_t>(65535, raw - pos);
      z.insert(z.end(), {static_cast<unsigned char>(pos + len == raw),
                         static_cast<unsigned char>(len), static_cast<unsigned char>(len >> 8),
                         static_cast<unsigned char>(~len), static_cast<unsigned char>(~len >> 8)});
      z.insert(z.end(), data.begin(), data.begin() + static_cast<std::ptrdiff_t>(len));
      pos += len;
    }
    for (int k = 0; k < 4; ++k) z.push_back(k == 3 ? 1 : 0);  // Adler-32 is not checked
    std::string png("\x89PNG\r\n\x1a\n\0\0\0\x0dIHDR", 16);
    for (const std::uint32_t v : {w, h})
      for (int sh = 24; sh >= 0; sh -= 8) png.push_back(static_cast<char>((v >> sh) & 0xFF));
    png += std::string("\x10\0\0\0\0\0\0\0\0", 9);
    for (int sh = 24; sh >= 0; sh -= 8) png.push_back(static_cast<char>((z.size() >> sh) & 0xFF));
    png += "IDAT";
    png.append(reinterpret_cast<const char*>(z.data()), z.size());
    png += std::string(4, '\0') + std::string("\0\0\0\0IEND\xae\x42\x60\x82", 12);
    std::ofstream(dir / name, std::ios::binary) << png;
    return dir / name;
  };
  // 1x1 at 16 bits is 3 bytes: a filter byte and one sample.
  EXPECT_EQ(read_depth_png(png_of("exact.png", 1, 1, 3)).data, std::vector<std::uint16_t>{0});
  const std::filesystem::path bomb = png_of("bomb.png", 1, 1, 1 << 20);
  EXPECT_EQ(test::error_of([&] { (void)read_depth_png(bomb); }),
            bomb.string() +
                ": not a readable PNG (its image data does not inflate to the 3 bytes "
                "of its 1x1 pixels: corrupt, or longer than they hold)");
}

// The size cap is read from the header before anything is decoded: twice the SR300's
// largest stream (1920x1080) in pixels, 4096 a side (the issue: a 39 KB 4096x4096 PNG cost
// 750 MB and 30 s).
TEST_F(DepthPng, ImagesLargerThanACameraDeliversAreRefusedFromTheHeader) {
  const auto header_only = [&](const char* name, std::uint32_t w, std::uint32_t h) {
    std::string png("\x89PNG\r\n\x1a\n\0\0\0\x0dIHDR", 16);
    for (const std::uint32_t v : {w, h})
      for (int s = 24; s >= 0; s -= 8) png.push_back(static_cast<char>((v >> s) & 0xFF));
    png += std::string("\x10\0\0\0\0\0\0\0\0", 9);
    std::ofstream(dir / name, std::ios::binary) << png << std::string(1000, '\0');
    return test::error_of([&] { (void)read_depth_png(dir / name); });
  };
  const std::string limits =
      " pixels is more than a camera image may have (4194304 pixels, 4096 a side)";
  EXPECT_EQ(header_only("big.png", 4096, 4096),
            (dir / "big.png").string() + ": 4096x4096" + limits);
  EXPECT_EQ(header_only("side.png", 4097, 1), (dir / "side.png").string() + ": 4097x1" + limits);
  // Under the cap the header passes and the decoder says what is wrong with the rest.
  EXPECT_EQ(header_only("hd.png", 1920, 1080).find(limits), std::string::npos);
  DepthImage hd{1920, 1080, std::vector<std::uint16_t>(1920 * 1080, 700)};
  write_depth_png(dir / "hd_ok.png", hd);
  EXPECT_EQ(read_depth_png(dir / "hd_ok.png").data.size(), hd.data.size());
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
