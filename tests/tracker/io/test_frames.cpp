#include <gtest/gtest.h>

#include <fstream>

#include "linksight/io/error.hpp"
#include "linksight/io/frames.hpp"
#include "test_support.hpp"

namespace linksight::io {
namespace {

TEST(NaturalSort, NumbersByValue) {
  EXPECT_TRUE(natural_less("frame2.png", "frame10.png"));
  EXPECT_FALSE(natural_less("frame10.png", "frame2.png"));
  EXPECT_TRUE(natural_less("a/0.png", "a/100.png"));
  EXPECT_TRUE(natural_less("f1", "f01"));
  EXPECT_FALSE(natural_less("x", "x"));
  EXPECT_TRUE(natural_less("abc", "abd"));
}

class Frames : public ::testing::Test {
 protected:
  std::filesystem::path dir =
      test::scratch_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
  void touch(const std::string& name) { std::ofstream(dir / name) << "x"; }
};

TEST_F(Frames, DirectoryInNaturalOrderSkippingOtherFiles) {
  for (const char* n : {"10.png", "2.png", "1.png", "notes.txt", "100.PNG"}) touch(n);
  const auto f = list_frames(dir.string());
  ASSERT_EQ(f.size(), 4u);
  EXPECT_EQ(f[0].filename(), "1.png");
  EXPECT_EQ(f[1].filename(), "2.png");
  EXPECT_EQ(f[2].filename(), "10.png");
  EXPECT_EQ(f[3].filename(), "100.PNG");
}

TEST_F(Frames, GlobAndSingleFile) {
  for (const char* n : {"a_3.ply", "a_20.ply", "b_1.ply"}) touch(n);
  const auto g = list_frames((dir / "a_*.ply").string());
  ASSERT_EQ(g.size(), 2u);
  EXPECT_EQ(g[0].filename(), "a_3.ply");
  EXPECT_EQ(list_frames((dir / "b_1.ply").string()).size(), 1u);
}

TEST_F(Frames, ErrorsNameTheInput) {
  auto message = [](const std::string& input) {
    try {
      (void)list_frames(input);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(message(dir.string()), dir.string() + ": directory has no frames (*.ply, *.png)");
  EXPECT_EQ(message((dir / "none").string()),
            (dir / "none").string() + ": no such file or directory");
  // Issue 19: a device is there, but not a frame ("no such file" was wrong).
  EXPECT_EQ(message("/dev/zero"),
            "/dev/zero: not a regular file or directory (a device, pipe or socket)");
  EXPECT_EQ(message((dir / "*.ply").string()),
            (dir / "*.ply").string() + ": pattern matches no file");
  touch("notes.txt");
  EXPECT_NE(message((dir / "notes.txt").string()).find("unsupported frame type"),
            std::string::npos);
}

TEST_F(Frames, IntrinsicsBesideOrInParent) {
  std::filesystem::create_directories(dir / "frames");
  touch("intrinsics.json");
  EXPECT_EQ(find_intrinsics(dir / "frames" / "0.png", std::nullopt), dir / "intrinsics.json");
  std::filesystem::remove(dir / "intrinsics.json");
  EXPECT_THROW((void)find_intrinsics(dir / "frames" / "0.png", std::nullopt), InputError);
  EXPECT_EQ(find_intrinsics(dir / "0.png", dir / "k.json"), dir / "k.json");
}

}  // namespace
}  // namespace linksight::io
