// nodes_csv.hpp: an estimate's nodes per frame, what `linksight score` reads; every
// refusal names the file and line.
#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "linksight/io/error.hpp"
#include "linksight/io/nodes_csv.hpp"
#include "test_support.hpp"

namespace linksight::io {
namespace {
namespace fs = std::filesystem;

// The error reading `text` as a table of `frames` x `nodes` gives ("" when it reads).
std::string error_of(const fs::path& dir, const std::string& text, std::size_t frames,
                     std::size_t nodes) {
  std::ofstream(dir / "nodes.csv") << text;
  try {
    (void)read_nodes_csv(dir / "nodes.csv", frames, nodes);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(NodesCsv, ReadsAnyColumnOrderAndLeavesMissingFramesEmpty) {
  const fs::path dir = test::scratch_dir("NodesCsv.ReadsAnyColumnOrder");
  // Extra columns (run's nodes.csv has mode and the truth) are ignored; rows in any order.
  std::ofstream(dir / "a.csv") << "mode,z_m,node,frame,x_m,y_m,err_mm\r\n"
                               << "m,0.6,1,2,0.01,0.02,1\r\n"
                               << "m,0.7,0,2,-0.01,0.5,1\r\n"
                               << "m,0.8,0,0,1e-3,2,1\r\n"
                               << "m,0.9,1,0,0,0,1\r\n";
  const auto t = read_nodes_csv(dir / "a.csv", 4, 2);
  ASSERT_EQ(t.size(), 4u);
  ASSERT_TRUE(t[0] && t[2]);
  EXPECT_FALSE(t[1]);
  EXPECT_FALSE(t[3]);
  EXPECT_EQ((*t[2])[1], Eigen::Vector3d(0.01, 0.02, 0.6));
  EXPECT_EQ((*t[2])[0], Eigen::Vector3d(-0.01, 0.5, 0.7));
  EXPECT_EQ((*t[0])[0], Eigen::Vector3d(1e-3, 2, 0.8));
  // Sizes from the file itself.
  const auto inferred = read_nodes_csv(dir / "a.csv");
  EXPECT_EQ(inferred.size(), 3u);
  EXPECT_EQ(inferred[0]->size(), 2u);
}

TEST(NodesCsv, RefusalsNameTheFileAndLine) {
  const fs::path dir = test::scratch_dir("NodesCsv.Refusals");
  const std::string h = "frame,node,x_m,y_m,z_m\n";
  struct Case {
    std::string text, expect;
  };
  for (const Case& c : {
           Case{"frame,node,x_m,y_m\n0,0,1,2\n", "nodes.csv:1: no column 'z_m'"},
           Case{"frame,node,x_m,y_m,z_m,x_m\n0,0,1,2,3,4\n", "nodes.csv:1: column 'x_m' given twice"},
           Case{h + "0,0,0,0,0\n0,1,0,0,0\n0,0,1,1,1\n",
                "nodes.csv:4: frame 0 node 0 given twice (first on line 2)"},
           Case{h + "0,0,0,0,0\n0,1,nan,0,0\n", "nodes.csv:3: x_m 'nan' is not a finite number"},
           Case{h + "0,0,0,0,1e999\n0,1,0,0,0\n", "nodes.csv:2: z_m '1e999' is not a finite number"},
           Case{h + "0,0,0,0,0\n0,1,0,0,0\n5,0,0,0,0\n",
                "nodes.csv:4: frame 5 is not among the truth's 3 frames"},
           Case{h + "0,2,0,0,0\n", "nodes.csv:2: node 2 is not among the truth's 2 nodes per frame (0..1)"},
           Case{h + "-1,0,0,0,0\n", "nodes.csv:2: frame '-1' is not an index"},
           Case{h + "0,0,0,0,0\n0,1,0,0,0\n1,1,0,0,0\n", "nodes.csv:4: frame 1 has 1 of the 2 nodes"},
           Case{h + "0,0,0,0\n", "nodes.csv:2: 4 fields, expected 5"},
           Case{h + "0,1,0,0,0\n0,0,0,0,101\n", "nodes.csv:3: z_m '101' is beyond 100 m"},
       }) {
    const std::string e = error_of(dir, c.text, 3, 2);
    EXPECT_NE(e.find(c.expect), std::string::npos) << "got: " << e << "\nfor:\n" << c.text;
  }
  EXPECT_EQ(error_of(dir, h + "0,0,0,0,0\n0,1,0,0,0\n", 3, 2), "");
}

// Sizes read from the file itself cannot be made to allocate more than its rows: a frame
// that names a node far beyond its row count is refused before any table exists, and a
// node index no chain has is refused outright.
TEST(NodesCsv, InferredSizesAreBoundedByTheRows) {
  const fs::path dir = test::scratch_dir("NodesCsv.InferredSizes");
  std::string text = "frame,node,x_m,y_m,z_m\n";
  for (int f = 0; f < 200; ++f) text += std::to_string(f) + ",999,0,0,0\n";
  EXPECT_NE(error_of(dir, text, 0, 0).find("nodes.csv:2: frame 0 has 1 of the 1000 nodes"),
            std::string::npos);
  EXPECT_NE(error_of(dir, "frame,node,x_m,y_m,z_m\n0,5000,0,0,0\n", 0, 0)
                .find("nodes.csv:2: node 5000 is more than 1000"),
            std::string::npos);
  EXPECT_NE(error_of(dir, "frame,node,x_m,y_m,z_m\n0,0,0,0,0\n5,900,0,0,0\n", 0, 0)
                .find("nodes.csv:2: frame 0 has 1 of the 901 nodes"),
            std::string::npos);
  EXPECT_NE(error_of(dir, "frame,node,x_m,y_m,z_m\n1000001,0,0,0,0\n", 0, 0)
                .find("nodes.csv:2: frame '1000001' is not an index"),
            std::string::npos);
}

}  // namespace
}  // namespace linksight::io
