#include "linksight/sim/mesh.hpp"

#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <csignal>
#include <cstdint>
#include <assimp/Importer.hpp>
#include <cmath>
#include <iomanip>
#include <numbers>
#include <ostream>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "linksight/io/atomic_file.hpp"
#include "linksight/io/error.hpp"

namespace linksight::sim {
namespace {

/// One latitude ring of a surface of revolution about Z: ring radius and height.
struct Ring {
  double rho;
  double z;
};

/// Cos/sin with the tiny residues at multiples of pi/2 snapped to zero, so the OBJ
/// file shows 0 rather than 1e-19.
double snap(double v) { return std::abs(v) < 1e-12 ? 0.0 : v; }

/// Appends the closed surface of revolution with poles at (0,0,z_bottom) and
/// (0,0,z_top) and the given interior rings (bottom to top), `slices` around Z,
/// triangles oriented outward.
void append_lathe(TriangleMesh& mesh, double z_bottom, double z_top, const std::vector<Ring>& rings,
                  int slices) {
  const int base = static_cast<int>(mesh.vertices.size());
  const int n_rings = static_cast<int>(rings.size());
  const int bottom = base;
  const int top = base + 1 + n_rings * slices;
  mesh.vertices.emplace_back(0.0F, 0.0F, static_cast<float>(z_bottom));
  for (const Ring& ring : rings) {
    for (int j = 0; j < slices; ++j) {
      const double phi = 2.0 * std::numbers::pi * j / slices;
      mesh.vertices.emplace_back(static_cast<float>(snap(std::cos(phi)) * ring.rho),
                                 static_cast<float>(snap(std::sin(phi)) * ring.rho),
                                 static_cast<float>(ring.z));
    }
  }
  mesh.vertices.emplace_back(0.0F, 0.0F, static_cast<float>(z_top));
  const auto at = [&](int ring, int j) { return base + 1 + ring * slices + (j % slices); };
  for (int j = 0; j < slices; ++j) mesh.triangles.emplace_back(bottom, at(0, j + 1), at(0, j));
  for (int i = 0; i + 1 < n_rings; ++i) {
    for (int j = 0; j < slices; ++j) {
      const int a = at(i, j), b = at(i, j + 1), c = at(i + 1, j + 1), d = at(i + 1, j);
      mesh.triangles.emplace_back(a, b, c);
      mesh.triangles.emplace_back(a, c, d);
    }
  }
  for (int j = 0; j < slices; ++j)
    mesh.triangles.emplace_back(at(n_rings - 1, j), at(n_rings - 1, j + 1), top);
}

/// Interior rings of a capsule of radius `radius` around (0,0,z0)-(0,0,z1), each
/// hemisphere in `bands` latitude bands; a sphere when z0 == z1.
std::vector<Ring> capsule_rings(double radius, double z0, double z1, int bands) {
  std::vector<Ring> rings;
  for (int k = 1; k <= bands; ++k) {  // bottom hemisphere, up to its equator at z0
    const double theta = std::numbers::pi / 2.0 * k / bands;  // from the bottom pole
    rings.push_back({snap(std::sin(theta)) * radius, z0 - snap(std::cos(theta)) * radius});
  }
  for (int k = z1 > z0 ? 0 : 1; k < bands; ++k) {  // top hemisphere, from its equator at z1
    const double theta = std::numbers::pi / 2.0 * k / bands;  // from the equator
    rings.push_back({snap(std::cos(theta)) * radius, z1 + snap(std::sin(theta)) * radius});
  }
  return rings;
}

void append_mesh(TriangleMesh& out, const aiScene& scene, const aiNode& node,
                 const aiMatrix4x4& parent) {
  const aiMatrix4x4 transform = parent * node.mTransformation;
  for (unsigned m = 0; m < node.mNumMeshes; ++m) {
    const aiMesh& mesh = *scene.mMeshes[node.mMeshes[m]];
    const int base = static_cast<int>(out.vertices.size());
    for (unsigned v = 0; v < mesh.mNumVertices; ++v) {
      const aiVector3D p = transform * mesh.mVertices[v];
      out.vertices.emplace_back(p.x, p.y, p.z);
    }
    for (unsigned f = 0; f < mesh.mNumFaces; ++f) {
      const aiFace& face = mesh.mFaces[f];
      if (face.mNumIndices != 3) continue;  // points and lines
      out.triangles.emplace_back(base + static_cast<int>(face.mIndices[0]),
                                 base + static_cast<int>(face.mIndices[1]),
                                 base + static_cast<int>(face.mIndices[2]));
    }
  }
  for (unsigned c = 0; c < node.mNumChildren; ++c)
    append_mesh(out, scene, *node.mChildren[c], transform);
}

}  // namespace

TriangleMesh component_mesh(const ComponentGeometry& geometry, int segments) {
  geometry.validate();
  if (segments < 4)
    throw std::invalid_argument("segments = " + std::to_string(segments) + ": must be >= 4");
  const int bands = segments / 4;
  const double r = geometry.ball_radius;
  const double rn = geometry.neck_radius;
  const double len = geometry.neck_length;
  TriangleMesh mesh;
  append_lathe(mesh, -r, r, capsule_rings(r, 0.0, 0.0, bands), segments);
  append_lathe(mesh, -rn, len + rn, capsule_rings(rn, 0.0, len, bands), segments);
  return mesh;
}

TriangleMesh box_mesh(const Eigen::Vector3d& h) {
  if (!(h.minCoeff() > 0) || !h.allFinite())
    throw std::invalid_argument("box half extents must all be > 0");
  TriangleMesh mesh;
  for (int i = 0; i < 8; ++i) {
    mesh.vertices.emplace_back(static_cast<float>((i & 1) ? h.x() : -h.x()),
                               static_cast<float>((i & 2) ? h.y() : -h.y()),
                               static_cast<float>((i & 4) ? h.z() : -h.z()));
  }
  // Two triangles per face, counter-clockwise seen from outside.
  const int faces[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                           {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& f : faces) {
    mesh.triangles.emplace_back(f[0], f[1], f[2]);
    mesh.triangles.emplace_back(f[0], f[2], f[3]);
  }
  return mesh;
}

TriangleMesh cylinder_mesh(double radius, double half_length, int slices) {
  if (!(radius > 0) || !(half_length > 0) || slices < 3)
    throw std::invalid_argument("cylinder: need radius > 0, half_length > 0, slices >= 3");
  TriangleMesh mesh;
  append_lathe(mesh, -half_length, half_length, {{radius, -half_length}, {radius, half_length}},
               slices);
  return mesh;
}

TriangleMesh sphere_mesh(double radius, int segments) {
  if (!(radius > 0) || segments < 4)
    throw std::invalid_argument("sphere: need radius > 0 and segments >= 4");
  TriangleMesh mesh;
  append_lathe(mesh, -radius, radius, capsule_rings(radius, 0.0, 0.0, segments / 4), segments);
  return mesh;
}

void append(TriangleMesh& mesh, const TriangleMesh& part, const Eigen::Isometry3d& X) {
  const int base = static_cast<int>(mesh.vertices.size());
  for (const Eigen::Vector3f& v : part.vertices)
    mesh.vertices.push_back((X * v.cast<double>()).cast<float>());
  for (const Eigen::Vector3i& t : part.triangles)
    mesh.triangles.push_back(t + Eigen::Vector3i::Constant(base));
}

TriangleMesh hand_mesh() {
  auto at = [](double x, double y, double z, double tilt_about_y = 0.0) {
    Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
    X.linear() = Eigen::AngleAxisd(tilt_about_y, Eigen::Vector3d::UnitY()).toRotationMatrix();
    X.translation() = Eigen::Vector3d(x, y, z);
    return X;
  };
  TriangleMesh m;
  append(m, box_mesh({0.042, 0.012, 0.05}));                        // palm
  const double lengths[4] = {0.032, 0.040, 0.037, 0.030};           // index .. little
  for (int f = 0; f < 4; ++f)
    append(m, cylinder_mesh(0.009, lengths[f], 24), at(-0.0315 + 0.021 * f, 0, 0.05 + lengths[f]));
  append(m, cylinder_mesh(0.011, 0.03, 24), at(0.055, 0, 0.01, 0.6));  // thumb
  append(m, cylinder_mesh(0.03, 0.12, 32), at(0, 0, -0.16));           // forearm
  return m;
}

TriangleMesh mug_mesh() {
  TriangleMesh m;
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.translation() = Eigen::Vector3d(0, 0, 0.05);
  append(m, cylinder_mesh(0.04, 0.05, 48), X);
  X.translation() = Eigen::Vector3d(0.05, 0, 0.05);
  append(m, box_mesh({0.012, 0.006, 0.03}), X);  // handle
  return m;
}

void write_obj(const std::filesystem::path& path, const TriangleMesh& mesh,
               const std::string& comment) {
  const auto n = static_cast<long long>(mesh.vertices.size());
  for (const Eigen::Vector3i& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) {
      if (t[k] < 0 || t[k] >= n)
        throw std::invalid_argument("write_obj: triangle index " + std::to_string(t[k]) +
                                    " out of range [0, " + std::to_string(n) + ")");
    }
  }
  io::write_file_atomic(path, [&](std::ostream& out) {
    if (!comment.empty()) {
      std::istringstream lines(comment);
      for (std::string line; std::getline(lines, line);) out << "# " << line << '\n';
    }
    out << std::fixed << std::setprecision(9);
    for (const Eigen::Vector3f& v : mesh.vertices) {
      out << "v " << static_cast<double>(v.x()) << ' ' << static_cast<double>(v.y()) << ' '
          << static_cast<double>(v.z()) << '\n';
    }
    for (const Eigen::Vector3i& t : mesh.triangles)
      out << "f " << t[0] + 1 << ' ' << t[1] + 1 << ' ' << t[2] + 1 << '\n';
  });
}

namespace {
// The reading itself, in this process.
TriangleMesh read_with_assimp(const std::filesystem::path& path) {
  Assimp::Importer importer;
  const aiScene* scene =
      importer.ReadFile(path.string(), aiProcess_Triangulate | aiProcess_JoinIdenticalVertices);
  if (scene == nullptr) throw io::InputError(path.string() + ": " + importer.GetErrorString());
  if ((scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE) != 0 || scene->mRootNode == nullptr)
    throw io::InputError(path.string() + ": incomplete scene");
  TriangleMesh mesh;
  append_mesh(mesh, *scene, *scene->mRootNode, aiMatrix4x4());
  if (mesh.triangles.empty()) throw io::InputError(path.string() + ": no triangles");
  return mesh;
}

// The child sends the arrays as they lie in memory: three packed 4-byte values each.
static_assert(sizeof(Eigen::Vector3f) == 12 && sizeof(Eigen::Vector3i) == 12);

// Writes all of `n` bytes (false: the pipe closed).
bool put(int fd, const void* data, std::size_t n) {
  const char* p = static_cast<const char*>(data);
  while (n > 0) {
    const ssize_t w = ::write(fd, p, n);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) return false;
    p += w;
    n -= static_cast<std::size_t>(w);
  }
  return true;
}

// Reads all of `n` bytes (false: the writer ended first).
bool get(int fd, void* data, std::size_t n) {
  char* p = static_cast<char*>(data);
  while (n > 0) {
    const ssize_t r = ::read(fd, p, n);
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) return false;
    p += r;
    n -= static_cast<std::size_t>(r);
  }
  return true;
}
}  // namespace

// Debian builds assimp with its assertions on, so a malformed file can abort() inside it
// (fuzz_mesh: an OFF file whose vertex count lies trips an ai_assert in TriangulateProcess).
// The file is read in a child process: its crash is an InputError naming the file, not the
// end of linksight. The child sends the mesh (or the error) back over a pipe and leaves
// with _exit, flushing nothing of the parent's.
TriangleMesh load_mesh(const std::filesystem::path& path) {
  const std::string file = path.string();
  int fds[2];
  if (::pipe(fds) != 0) throw io::InputError(file + ": cannot read the mesh (no pipe)");
  const pid_t child = ::fork();
  if (child < 0) {
    ::close(fds[0]);
    ::close(fds[1]);
    throw io::InputError(file + ": cannot read the mesh (no process)");
  }
  if (child == 0) {
    ::close(fds[0]);
    // The parent's handlers (the CLI's Ctrl-C flag, a fuzzer's or sanitizer's crash
    // report) are not the child's: a crash in assimp ends the child by its signal, which
    // the parent names; Ctrl-C ends it too.
    for (const int sig : {SIGABRT, SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGINT, SIGTERM})
      std::signal(sig, SIG_DFL);
    std::uint8_t ok = 0;
    std::string error;
    TriangleMesh m;
    try {
      m = read_with_assimp(path);
      ok = 1;
    } catch (const std::exception& e) {
      error = e.what();
    }
    const std::uint64_t a = ok ? m.vertices.size() : error.size();
    const std::uint64_t b = ok ? m.triangles.size() : 0;
    bool sent = put(fds[1], &ok, 1) && put(fds[1], &a, 8) && put(fds[1], &b, 8);
    if (ok) {
      sent = sent && put(fds[1], m.vertices.data(), m.vertices.size() * 12) &&
             put(fds[1], m.triangles.data(), m.triangles.size() * 12);
    } else {
      sent = sent && put(fds[1], error.data(), error.size());
    }
    ::_exit(sent ? 0 : 3);
  }
  ::close(fds[1]);
  std::uint8_t ok = 0;
  std::uint64_t a = 0, b = 0;
  bool got = get(fds[0], &ok, 1) && get(fds[0], &a, 8) && get(fds[0], &b, 8);
  TriangleMesh mesh;
  std::string error;
  // The child counted what it sends; a bound still keeps a broken count from allocating.
  constexpr std::uint64_t kMaxItems = std::uint64_t{1} << 28;
  got = got && a <= kMaxItems && b <= kMaxItems;
  if (got && ok) {
    mesh.vertices.resize(a);
    mesh.triangles.resize(b);
    got = get(fds[0], mesh.vertices.data(), a * 12) && get(fds[0], mesh.triangles.data(), b * 12);
  } else if (got) {
    error.resize(a);
    got = get(fds[0], error.data(), a);
  }
  ::close(fds[0]);
  int status = 0;
  while (::waitpid(child, &status, 0) < 0 && errno == EINTR) {
  }
  if (WIFSIGNALED(status))
    throw io::InputError(file + ": the mesh reader (assimp) crashed on this file (signal " +
                         std::to_string(WTERMSIG(status)) + "): not a mesh it can read");
  if (!got || !WIFEXITED(status) || WEXITSTATUS(status) != 0)
    throw io::InputError(file + ": the mesh reader (assimp) ended without a mesh");
  if (!ok) throw io::InputError(error);
  return mesh;
}

void DepthSurfaceParams::validate() const {
  if (max_gap_px < 0)
    throw std::invalid_argument("depth surface max_gap_px = " + std::to_string(max_gap_px) +
                                ": must be >= 0");
  if (!(jump > 0))
    throw std::invalid_argument("depth surface jump = " + std::to_string(jump) + ": must be > 0 m");
  if (!(smoothing_px >= 0 && smoothing_px <= 20))
    throw std::invalid_argument("depth surface smoothing_px = " + std::to_string(smoothing_px) +
                                ": must be in [0, 20]");
}

TriangleMesh depth_surface_mesh(const io::DepthImage& depth, const io::Intrinsics& K,
                                const DepthSurfaceParams& p) {
  p.validate();
  const int W = depth.width, H = depth.height;
  if (W != K.width || H != K.height)
    throw std::invalid_argument("depth surface: the image is " + std::to_string(W) + "x" +
                                std::to_string(H) + ", the intrinsics say " +
                                std::to_string(K.width) + "x" + std::to_string(K.height));
  const auto idx = [W](int u, int v) { return static_cast<std::size_t>(v) * W + u; };
  std::vector<double> z(depth.data.size(), 0.0);
  bool any = false;
  for (std::size_t i = 0; i < z.size(); ++i) {
    z[i] = depth.data[i] * K.depth_scale;
    any = any || depth.data[i] != 0;
  }
  if (!any) throw std::invalid_argument("depth surface: no valid pixel");
  // Gaps along rows, then what is left along columns; both read the original image.
  std::vector<double> filled = z;
  auto fill_line = [&](int count, int length, auto at) {
    for (int l = 0; l < count; ++l) {
      int last = -1;  // the last valid pixel before a gap
      for (int i = 0; i < length; ++i) {
        if (z[at(l, i)] <= 0) continue;
        const int gap = i - last - 1;
        if (last >= 0 && gap > 0 && gap <= p.max_gap_px) {
          const double za = z[at(l, last)], zb = z[at(l, i)];
          for (int k = last + 1; k < i; ++k) {
            if (filled[at(l, k)] > 0) continue;
            const double f = static_cast<double>(k - last) / (i - last);
            filled[at(l, k)] = std::abs(zb - za) > p.jump ? std::max(za, zb) : za + f * (zb - za);
          }
        }
        last = i;
      }
    }
  };
  fill_line(H, W, [&](int v, int u) { return idx(u, v); });
  fill_line(W, H, [&](int u, int v) { return idx(u, v); });
  // Edge-preserving smoothing: a Gaussian over the neighbours on the same surface (within
  // 3 jump of the centre), along rows then along columns. A Gaussian leaves a quadratic
  // surface as it is up to a constant, so the curvature a plane fit sees survives; the
  // camera's noise does not.
  std::vector<double> smooth = filled;
  if (p.smoothing_px > 0) {
    const int R = static_cast<int>(std::ceil(3 * p.smoothing_px));
    std::vector<double> g(static_cast<std::size_t>(R) + 1);
    for (int i = 0; i <= R; ++i) g[i] = std::exp(-0.5 * i * i / (p.smoothing_px * p.smoothing_px));
    // Wider than `jump`: a steep surface changes by more than `jump` across the kernel, and
    // cutting it there would keep one side only and bend the slope.
    const double gate = 3 * p.jump;
    auto pass = [&](const std::vector<double>& src, std::vector<double>& dst, bool rows) {
      for (int v = 0; v < H; ++v)
        for (int u = 0; u < W; ++u) {
          const double z0 = src[idx(u, v)];
          if (z0 <= 0) continue;
          double sw = 0, sz = 0;
          for (int d = -R; d <= R; ++d) {
            const int uu = rows ? u + d : u, vv = rows ? v : v + d;
            if (uu < 0 || uu >= W || vv < 0 || vv >= H) continue;
            const double zq = src[idx(uu, vv)];
            if (zq <= 0 || std::abs(zq - z0) > gate) continue;
            sw += g[std::abs(d)];
            sz += g[std::abs(d)] * zq;
          }
          dst[idx(u, v)] = sz / sw;
        }
    };
    std::vector<double> tmp = filled;
    pass(filled, tmp, true);
    pass(tmp, smooth, false);
  }
  TriangleMesh mesh;
  std::vector<int> vertex(smooth.size(), -1);
  // Each vertex sits kVertexOffPx off its pixel's ray, diagonally, so that the ray meets
  // the inside of a triangle: through exactly a shared vertex, Embree's robust triangle
  // test can let a ray pass every triangle (RenderKit/embree#174, #181), and an unjittered
  // re-render of this mesh came back with one-pixel holes (about 650 per hand frame).
  // 0.01 px is about 13 um at 0.6 m: far below what a window's fit reads.
  constexpr double kVertexOffPx = 0.01;
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u) {
      if (smooth[idx(u, v)] <= 0) continue;
      vertex[idx(u, v)] = static_cast<int>(mesh.vertices.size());
      mesh.vertices.push_back(
          K.deproject(u + kVertexOffPx, v + kVertexOffPx, smooth[idx(u, v)]).cast<float>());
    }
  auto close = [&](std::size_t a, std::size_t b, std::size_t c) {
    const double lo = std::min({smooth[a], smooth[b], smooth[c]});
    const double hi = std::max({smooth[a], smooth[b], smooth[c]});
    return lo > 0 && hi - lo <= p.jump;
  };
  for (int v = 0; v + 1 < H; ++v)
    for (int u = 0; u + 1 < W; ++u) {
      const std::size_t a = idx(u, v), b = idx(u + 1, v), c = idx(u, v + 1), d = idx(u + 1, v + 1);
      // Counter-clockwise seen from the camera (x right, y down, z forward).
      if (close(a, c, b)) mesh.triangles.emplace_back(vertex[a], vertex[c], vertex[b]);
      if (close(b, c, d)) mesh.triangles.emplace_back(vertex[b], vertex[c], vertex[d]);
    }
  // The rim. The triangles end at the edge pixels' centres, and with kVertexOffPx a top or
  // left edge pixel's own ray meets no triangle at all, so a re-render lost about 16% of
  // the rim pixels the camera saw (ShapeRenderRim). Each pixel with an 8-neighbour off its
  // surface or off the image also gets a splat: its tangent plane over its own footprint,
  // half a pixel each way, kRimSplatBehind_m behind the pixel's depth, so that a ray that
  // meets the mesh keeps the mesh's depth (the nearest hit wins). "Behind" holds at the
  // centre: where the surface bulges towards the camera by more than that over half a pixel
  // the plane comes in front of the mesh's chords (132 pixels of the 11 hand frames'
  // jittered renders, at most 1.5 mm; docs/sensor.md). A pixel with no neighbour on its
  // surface (a stray the camera reported, about 3 a hand frame) gets a flat splat too.
  // Pixel b on pixel a's surface (a has a depth): the triangles' own rule.
  const auto same = [&](std::size_t a, std::size_t b) { return close(a, b, b); };
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u) {
      const std::size_t i = idx(u, v);
      if (smooth[i] <= 0) continue;
      bool rim = false;
      for (int dv = -1; dv <= 1 && !rim; ++dv)
        for (int du = -1; du <= 1 && !rim; ++du) {
          const int uu = u + du, vv = v + dv;
          rim = uu < 0 || vv < 0 || uu >= W || vv >= H || !same(i, idx(uu, vv));
        }
      if (!rim) continue;
      // Depth change per pixel along u or v, from the neighbours on the same surface.
      const auto slope = [&](int du, int dv) {
        const int u0 = u - du, v0 = v - dv, u1 = u + du, v1 = v + dv;
        const bool lo = u0 >= 0 && v0 >= 0 && same(i, idx(u0, v0));
        const bool hi = u1 < W && v1 < H && same(i, idx(u1, v1));
        if (lo && hi) return 0.5 * (smooth[idx(u1, v1)] - smooth[idx(u0, v0)]);
        if (hi) return smooth[idx(u1, v1)] - smooth[i];
        if (lo) return smooth[i] - smooth[idx(u0, v0)];
        return 0.0;
      };
      const double gu = slope(1, 0), gv = slope(0, 1);
      const int first = static_cast<int>(mesh.vertices.size());
      for (const auto& [cu, cv] : {std::pair{-0.5, -0.5}, std::pair{0.5, -0.5},
                                   std::pair{-0.5, 0.5}, std::pair{0.5, 0.5}}) {
        // Off by kVertexOffPx along u, so that the splat's diagonal, which runs through the
        // pixel's centre, misses its ray (Embree's robust test, above). The mesh's vertices
        // are off along v too, so at the ray the two differ by 0.01 px of the v slope as
        // well: on a surface that changes by `jump` (20 mm) a pixel along v that takes up the
        // whole kRimSplatBehind_m. The mesh's diagonal offset would not; kept as it is,
        // since the sr300 preset was fitted through this render.
        const double z_m = smooth[i] + gu * cu + gv * cv + kRimSplatBehind_m;
        mesh.vertices.push_back(K.deproject(u + cu + kVertexOffPx, v + cv, z_m).cast<float>());
      }
      mesh.triangles.emplace_back(first, first + 2, first + 1);
      mesh.triangles.emplace_back(first + 1, first + 2, first + 3);
    }
  return mesh;
}

}  // namespace linksight::sim
