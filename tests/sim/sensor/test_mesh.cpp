// The component mesh: two closed, outward-oriented shells (ball, neck capsule) whose
// volumes and extent match ComponentGeometry; the committed meshes/component.obj is
// current; load_mesh reports bad files as InputError naming the file.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <numeric>
#include <string>
#include <utility>
#include <vector>

#include "linksight/io/error.hpp"
#include "linksight/sim/mesh.hpp"
#include "test_support.hpp"

namespace linksight::sim {
namespace {

namespace fs = std::filesystem;

constexpr double kBoxTolerance = 0.5e-3;  // bounding box within 0.5 mm

/// Signed volume [m^3] of the triangles in `tris` (positive when outward-oriented).
double signed_volume(const TriangleMesh& m, const std::vector<Eigen::Vector3i>& tris) {
  double v = 0;
  for (const Eigen::Vector3i& t : tris) {
    const Eigen::Vector3d a = m.vertices[t[0]].cast<double>();
    const Eigen::Vector3d b = m.vertices[t[1]].cast<double>();
    const Eigen::Vector3d c = m.vertices[t[2]].cast<double>();
    v += a.dot(b.cross(c)) / 6.0;
  }
  return v;
}

/// Triangles grouped by connected component of the vertex graph (the mesh's parts).
std::vector<std::vector<Eigen::Vector3i>> parts(const TriangleMesh& m) {
  std::vector<int> parent(m.vertices.size());
  std::iota(parent.begin(), parent.end(), 0);
  const auto find = [&](int i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  for (const Eigen::Vector3i& t : m.triangles) {
    parent[find(t[1])] = find(t[0]);
    parent[find(t[2])] = find(t[0]);
  }
  std::map<int, std::vector<Eigen::Vector3i>> by_root;
  for (const Eigen::Vector3i& t : m.triangles) by_root[find(t[0])].push_back(t);
  std::vector<std::vector<Eigen::Vector3i>> out;
  for (auto& [root, tris] : by_root) out.push_back(std::move(tris));
  return out;
}

/// Closed and consistently oriented: every directed edge occurs exactly once and its
/// reverse exactly once, so every undirected edge is shared by exactly two triangles.
void expect_closed_oriented(const std::vector<Eigen::Vector3i>& tris) {
  std::map<std::pair<int, int>, int> directed;
  for (const Eigen::Vector3i& t : tris) {
    for (int k = 0; k < 3; ++k) ++directed[{t[k], t[(k + 1) % 3]}];
  }
  int bad = 0;
  for (const auto& [edge, n] : directed) {
    const auto reverse = directed.find({edge.second, edge.first});
    if (n != 1 || reverse == directed.end() || reverse->second != 1) ++bad;
  }
  EXPECT_EQ(bad, 0) << "edges not shared by exactly two consistently oriented triangles";
}

double ball_volume(const ComponentGeometry& g) {
  return 4.0 / 3.0 * std::numbers::pi * std::pow(g.ball_radius, 3);
}

double neck_volume(const ComponentGeometry& g) {
  const double rn = g.neck_radius;
  return std::numbers::pi * rn * rn * g.neck_length + 4.0 / 3.0 * std::numbers::pi * rn * rn * rn;
}

TEST(ComponentMesh, EachPartIsClosedAndOutwardOriented) {
  const ComponentGeometry g;
  for (int segments : {4, 7, 32, 64}) {
    SCOPED_TRACE("segments = " + std::to_string(segments));
    const TriangleMesh m = component_mesh(g, segments);
    for (const Eigen::Vector3i& t : m.triangles) {
      for (int k = 0; k < 3; ++k) {
        ASSERT_GE(t[k], 0);
        ASSERT_LT(t[k], static_cast<int>(m.vertices.size()));
      }
    }
    const auto shells = parts(m);
    ASSERT_EQ(shells.size(), 2U);  // ball and neck
    for (const auto& tris : shells) {
      expect_closed_oriented(tris);
      EXPECT_GT(signed_volume(m, tris), 0.0);
    }
  }
}

TEST(ComponentMesh, VolumeMatchesAnalyticWithinTwoPercent) {
  const ComponentGeometry g;
  const TriangleMesh m = component_mesh(g, 64);
  const double analytic = ball_volume(g) + neck_volume(g);  // separate shells: volumes add
  EXPECT_NEAR(signed_volume(m, m.triangles), analytic, 0.02 * analytic);
  // Each shell on its own, too (the larger one is the ball).
  auto shells = parts(m);
  ASSERT_EQ(shells.size(), 2U);
  std::vector<double> v{signed_volume(m, shells[0]), signed_volume(m, shells[1])};
  std::sort(v.begin(), v.end());
  EXPECT_NEAR(v[1], ball_volume(g), 0.02 * ball_volume(g));
  EXPECT_NEAR(v[0], neck_volume(g), 0.02 * neck_volume(g));
}

TEST(ComponentMesh, BoundingBoxMatchesGeometry) {
  const ComponentGeometry g;
  for (int segments : {32, 64}) {
    SCOPED_TRACE("segments = " + std::to_string(segments));
    const TriangleMesh m = component_mesh(g, segments);
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e9), hi = -lo;
    for (const Eigen::Vector3f& v : m.vertices) {
      lo = lo.cwiseMin(v.cast<double>());
      hi = hi.cwiseMax(v.cast<double>());
    }
    const double r = g.ball_radius;
    const double top = std::max(r, g.neck_length + g.neck_radius);
    EXPECT_LE((lo - Eigen::Vector3d(-r, -r, -r)).cwiseAbs().maxCoeff(), kBoxTolerance)
        << lo.transpose();
    EXPECT_LE((hi - Eigen::Vector3d(r, r, top)).cwiseAbs().maxCoeff(), kBoxTolerance)
        << hi.transpose();
  }
}

TEST(ComponentMesh, ZeroNeckLengthGivesASphericalNeck) {
  ComponentGeometry g;
  g.neck_length = 0;
  const TriangleMesh m = component_mesh(g, 16);
  const auto shells = parts(m);
  ASSERT_EQ(shells.size(), 2U);
  for (const auto& tris : shells) expect_closed_oriented(tris);
}

TEST(ComponentMesh, RejectsBadInput) {
  EXPECT_THROW((void)component_mesh(ComponentGeometry{}, 3), std::invalid_argument);
  ComponentGeometry g;
  g.neck_radius = -1;
  EXPECT_THROW((void)component_mesh(g), std::invalid_argument);
}

TEST(ComponentMesh, ObjRoundTripsThroughAssimp) {
  const fs::path dir = fs::temp_directory_path() / "linksight_test_mesh_roundtrip";
  fs::create_directories(dir);
  const TriangleMesh m = component_mesh(ComponentGeometry{}, 16);
  write_obj(dir / "c.obj", m, "two\ncomment lines");
  const TriangleMesh loaded = load_mesh(dir / "c.obj");
  ASSERT_EQ(loaded.vertices.size(), m.vertices.size());
  EXPECT_EQ(loaded.triangles.size(), m.triangles.size());
  EXPECT_NEAR(signed_volume(loaded, loaded.triangles), signed_volume(m, m.triangles), 1e-9);
  fs::remove_all(dir);
}

TEST(CommittedMesh, LoadsWithAssimpAndIsCurrent) {
  const fs::path path = fs::path(LINKSIGHT_MESH_DIR) / "component.obj";
  const TriangleMesh committed = load_mesh(path);
  const TriangleMesh fresh = component_mesh(ComponentGeometry{});
  EXPECT_EQ(committed.vertices.size(), fresh.vertices.size())
      << path << " is stale: regenerate with build/tools/linksight meshes --out meshes";
  EXPECT_EQ(committed.triangles.size(), fresh.triangles.size());
  const double v = signed_volume(fresh, fresh.triangles);
  EXPECT_NEAR(signed_volume(committed, committed.triangles), v, 1e-3 * v);
}

TEST(CommittedMesh, HandAndMugLoadAndAreCurrent) {
  for (const auto& [name, fresh] :
       {std::pair<const char*, TriangleMesh>{"hand.obj", hand_mesh()}, {"mug.obj", mug_mesh()}}) {
    const fs::path path = fs::path(LINKSIGHT_MESH_DIR) / name;
    const TriangleMesh committed = load_mesh(path);
    EXPECT_EQ(committed.triangles.size(), fresh.triangles.size())
        << path << " is stale: regenerate with build/tools/linksight meshes --out meshes";
    const double v = signed_volume(fresh, fresh.triangles);
    EXPECT_GT(v, 0) << name << ": parts must be closed and outward-oriented";
    EXPECT_NEAR(signed_volume(committed, committed.triangles), v, 1e-3 * v) << name;
  }
}

TEST(Primitives, BoxCylinderSphereVolumes) {
  EXPECT_NEAR(signed_volume(box_mesh({0.1, 0.2, 0.3}), box_mesh({0.1, 0.2, 0.3}).triangles),
              8 * 0.1 * 0.2 * 0.3, 1e-6 * 0.048);  // float vertices
  const TriangleMesh c = cylinder_mesh(0.05, 0.1, 256);
  EXPECT_NEAR(signed_volume(c, c.triangles), std::numbers::pi * 0.05 * 0.05 * 0.2, 1e-3 * 0.0016);
  const TriangleMesh s = sphere_mesh(0.05, 256);
  EXPECT_NEAR(signed_volume(s, s.triangles), 4.0 / 3 * std::numbers::pi * 1.25e-4, 1e-3 * 5.2e-4);
  EXPECT_THROW((void)box_mesh({0.1, 0.0, 0.1}), std::invalid_argument);
  EXPECT_THROW((void)cylinder_mesh(0.0, 0.1), std::invalid_argument);
}

TEST(LoadMesh, MissingFileThrowsInputErrorNamingTheFile) {
  const std::string path = (fs::temp_directory_path() / "linksight_no_such_mesh.obj").string();
  try {
    (void)load_mesh(path);
    FAIL() << "no exception";
  } catch (const io::InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(path + ": ", 0), 0U) << e.what();
  }
}

TEST(LoadMesh, GarbageFileThrowsInputErrorNamingTheFile) {
  const fs::path dir = fs::temp_directory_path() / "linksight_test_mesh_garbage";
  fs::create_directories(dir);
  for (const char* name : {"garbage.obj", "garbage.stl", "garbage.bin"}) {
    SCOPED_TRACE(name);
    const std::string path = (dir / name).string();
    {
      std::ofstream out(path, std::ios::binary);
      for (int i = 0; i < 256; ++i) out.put(static_cast<char>((i * 37 + 11) % 256));
    }
    try {
      (void)load_mesh(path);
      ADD_FAILURE() << "no exception";
    } catch (const io::InputError& e) {
      EXPECT_EQ(std::string(e.what()).rfind(path + ": ", 0), 0U) << e.what();
    }
  }
  fs::remove_all(dir);
}

// Issue 19, found by fuzz_mesh: an OFF file whose vertex count lies makes Debian's assimp
// abort() (an ai_assert in its TriangulateProcess). load_mesh reads in a child process, so
// this is an InputError naming the file, and the process goes on to read good meshes.
TEST(LoadMesh, AFileThatCrashesAssimpIsAnInputError) {
  const fs::path dir = fs::temp_directory_path() / "linksight_test_mesh_assert";
  fs::create_directories(dir);
  const std::string path = (dir / "liar.off").string();
  std::ofstream(path, std::ios::binary) << "OFF\n3 1 0\n0 0 0\n1 0 2 \n";
  try {
    (void)load_mesh(path);
    ADD_FAILURE() << "no exception";
  } catch (const io::InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(path + ": the mesh reader (assimp) crashed", 0), 0U)
        << e.what();
  }
  std::ofstream(dir / "ok.obj") << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  const TriangleMesh m = load_mesh(dir / "ok.obj");
  EXPECT_EQ(m.vertices.size(), 3u);
  ASSERT_EQ(m.triangles.size(), 1u);
  EXPECT_EQ(m.triangles[0], Eigen::Vector3i(0, 1, 2));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace linksight::sim

namespace linksight::sim {
namespace {

// depth_surface_mesh: a plane at 0.6 m with a near block at 0.5 m in front of it, the
// block's right edge followed by a 6-px invalid band and a 2-px hole in the plane. The
// band is filled with the far (plane) depth; no triangle spans the discontinuity; every
// vertex lies on its surface (smoothing keeps planes). The rim pixels (an 8-neighbour on
// the other surface or off the image) each add a splat of 4 vertices and 2 triangles,
// kRimSplatBehind_m behind their surface. Then a hole on a ramp: linear, and the ramp's
// splats follow its slope, along rows and along columns; and every triangle faces the camera.
TEST(DepthSurfaceMesh, FillsBandsAndHolesAndKeepsEdges) {
  io::Intrinsics K;
  K.width = 64;
  K.height = 48;
  K.fx = K.fy = 60;
  K.cx = 32;
  K.cy = 24;
  K.depth_scale = 0.000125;
  io::DepthImage d;
  d.width = K.width;
  d.height = K.height;
  d.data.assign(static_cast<std::size_t>(K.width) * K.height, 4800);  // 0.6 m
  for (int v = 10; v < 30; ++v)
    for (int u = 10; u < 40; ++u) {
      const std::size_t i = static_cast<std::size_t>(v) * K.width + u;
      if (u < 30) d.data[i] = 4000;  // 0.5 m
      else if (u < 36) d.data[i] = 0;  // the band right of the block
    }
  d.data[static_cast<std::size_t>(40) * K.width + 50] = 0;  // a hole
  d.data[static_cast<std::size_t>(40) * K.width + 51] = 0;
  const TriangleMesh m = depth_surface_mesh(d, K);
  // The rim: the image's border ring (2 x (64 + 48) - 4), the block's outermost ring of
  // 20 x 20 pixels (76) and the plane's ring around it (22 x 22 - 20 x 20: the band is
  // filled with the plane's depth, the hole with the plane's own).
  constexpr std::size_t kRim = 220 + 76 + 84;
  ASSERT_EQ(m.vertices.size(), d.data.size() + 4 * kRim) << "every pixel present after filling";
  for (std::size_t k = 0; k < m.vertices.size(); ++k) {
    const Eigen::Vector3f& p = m.vertices[k];
    const float behind = k < d.data.size() ? 0.0F : static_cast<float>(kRimSplatBehind_m);
    const bool near = std::abs(p.z() - 0.5F - behind) < 1e-4F;
    const bool far = std::abs(p.z() - 0.6F - behind) < 1e-4F;
    EXPECT_TRUE(near || far) << k << ": " << p.transpose();
  }
  int near = 0;
  for (const Eigen::Vector3i& t : m.triangles) {
    float lo = 1, hi = 0;
    for (int k = 0; k < 3; ++k) {
      lo = std::min(lo, m.vertices[static_cast<std::size_t>(t[k])].z());
      hi = std::max(hi, m.vertices[static_cast<std::size_t>(t[k])].z());
    }
    EXPECT_LT(hi - lo, 0.02F) << "a triangle across the discontinuity";
    near += hi < 0.55F;
  }
  EXPECT_EQ(near, 2 * 19 * 19 + 2 * 76) << "the block's 20 x 20 pixels make 19 x 19 quads";
  // Every triangle of the 2x2 blocks (split a-c-b, b-c-d) with its corners on one side of
  // the block's outline, the band and the hole included.
  auto in_block = [](int u, int v) { return u >= 10 && u < 30 && v >= 10 && v < 30; };
  std::size_t expected = 0;
  for (int v = 0; v + 1 < K.height; ++v)
    for (int u = 0; u + 1 < K.width; ++u) {
      const bool a = in_block(u, v), b = in_block(u + 1, v), c = in_block(u, v + 1),
                 dd = in_block(u + 1, v + 1);
      expected += (a == c && c == b) + (b == c && c == dd);
    }
  EXPECT_EQ(m.triangles.size(), expected + 2 * kRim);
  // A hole on a slope is filled linearly, not with either side: a ramp along rows, 1 mm
  // deeper per pixel (within `jump` across the gap), with a 3-px hole mid-row.
  io::DepthImage ramp = d;
  for (int v = 0; v < K.height; ++v)
    for (int u = 0; u < K.width; ++u)
      ramp.data[static_cast<std::size_t>(v) * K.width + u] = static_cast<std::uint16_t>(4800 + 8 * u);
  for (int u = 30; u < 33; ++u) ramp.data[static_cast<std::size_t>(24) * K.width + u] = 0;
  DepthSurfaceParams no_smoothing;  // so that the filled depths are the fill's
  no_smoothing.smoothing_px = 0;
  const TriangleMesh r = depth_surface_mesh(ramp, K, no_smoothing);
  ASSERT_EQ(r.vertices.size(), ramp.data.size() + 4 * 220) << "the border ring's splats only";
  for (int u = 30; u < 33; ++u)
    EXPECT_NEAR(r.vertices[static_cast<std::size_t>(24) * K.width + u].z(), 0.6 + 0.001 * u, 1e-6)
        << u;
  // A splat's corners lie on the ramp's plane (at their own column, 0.01 px left of where
  // they are deprojected: off the pixel's ray), behind it.
  for (std::size_t k = ramp.data.size(); k < r.vertices.size(); ++k) {
    const Eigen::Vector3f& p = r.vertices[k];
    const double u = K.fx * p.x() / p.z() + K.cx - 0.01;
    EXPECT_NEAR(p.z(), 0.6 + 0.001 * u + kRimSplatBehind_m, 2e-6) << k << ": " << p.transpose();
  }
  // The same along columns: a ramp down the image, 1 mm deeper per row. The splats take the
  // slope along v from their neighbours as they take it along u (they are not offset along
  // v, so each corner lies on the plane at its own row).
  io::DepthImage down = ramp;
  for (int v = 0; v < K.height; ++v)
    for (int u = 0; u < K.width; ++u)
      down.data[static_cast<std::size_t>(v) * K.width + u] = static_cast<std::uint16_t>(4800 + 8 * v);
  const TriangleMesh c = depth_surface_mesh(down, K, no_smoothing);
  ASSERT_EQ(c.vertices.size(), down.data.size() + 4 * 220) << "the border ring's splats only";
  for (std::size_t k = down.data.size(); k < c.vertices.size(); ++k) {
    const Eigen::Vector3f& p = c.vertices[k];
    const double v = K.fy * p.y() / p.z() + K.cy;
    EXPECT_NEAR(p.z(), 0.6 + 0.001 * v + kRimSplatBehind_m, 2e-6) << k << ": " << p.transpose();
  }
  // Every triangle, the splats' included, faces the camera (counter-clockwise seen from it,
  // x right, y down): its normal points back along the ray to its centroid, so a back-face
  // test or a normal read off the mesh sees the surface as the camera does.
  for (const TriangleMesh* mesh : {&m, &r, &c})
    for (const Eigen::Vector3i& t : mesh->triangles) {
      const Eigen::Vector3f& p0 = mesh->vertices[static_cast<std::size_t>(t[0])];
      const Eigen::Vector3f& p1 = mesh->vertices[static_cast<std::size_t>(t[1])];
      const Eigen::Vector3f& p2 = mesh->vertices[static_cast<std::size_t>(t[2])];
      EXPECT_LT((p1 - p0).cross(p2 - p0).dot(p0 + p1 + p2), 0.0F) << t.transpose();
    }
  d.data.assign(d.data.size(), 0);
  EXPECT_THROW((void)depth_surface_mesh(d, K), std::invalid_argument);
  DepthSurfaceParams bad;
  bad.smoothing_px = -1;
  const std::string e =
      test::error_of<std::invalid_argument>([&] { (void)depth_surface_mesh(d, K, bad); });
  EXPECT_NE(e.find("smoothing_px"), std::string::npos) << e;
}

}  // namespace
}  // namespace linksight::sim
