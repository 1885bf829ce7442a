// base_pose.hpp: what render writes, track reads back; rows in any order; CR line ends.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "linksight/io/base_pose.hpp"
#include "linksight/io/csv.hpp"
#include "linksight/io/error.hpp"
#include "test_support.hpp"

namespace linksight::io {
namespace {
namespace fs = std::filesystem;

TEST(BasePose, WrittenPosesReadBack) {
  const fs::path dir = test::scratch_dir("BasePose.WrittenPosesReadBack");
  std::vector<Eigen::Isometry3d> poses;
  for (int f = 0; f < 3; ++f) {
    Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
    X.translation() = Eigen::Vector3d(-0.25 + 0.01 * f, 0.05, 0.6);
    // Turns past 180° too: the writer picks qw >= 0, the pose is the same.
    X.linear() = Eigen::AngleAxisd(1.5 * f, Eigen::Vector3d(1, 2, 3).normalized())
                     .toRotationMatrix();
    poses.push_back(X);
  }
  std::ostringstream rows;
  write_base_pose_header(rows);
  for (const int f : {2, 0, 1}) write_base_pose_row(rows, f, poses[static_cast<std::size_t>(f)]);
  std::string text = rows.str();
  // CR LF line ends read the same.
  std::string crlf;
  for (const char c : text) crlf += c == '\n' ? std::string("\r\n") : std::string(1, c);
  std::ofstream(dir / "base.csv") << crlf;
  const std::vector<Eigen::Isometry3d> back = read_base_poses(dir / "base.csv", 3);
  ASSERT_EQ(back.size(), 3u);
  for (std::size_t f = 0; f < 3; ++f) {
    EXPECT_LT((back[f].translation() - poses[f].translation()).norm(), 1e-9);
    EXPECT_LT((back[f].linear() - poses[f].linear()).norm(), 1e-8);
  }
  // Errors name the line: frame 2's row is line 2.
  std::ofstream(dir / "short.csv") << text;
  try {
    (void)read_base_poses(dir / "short.csv", 2);
    ADD_FAILURE() << "frame 2 of 2 frames was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("short.csv:2: frame 2 is not among the 2 input frames"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace linksight::io
