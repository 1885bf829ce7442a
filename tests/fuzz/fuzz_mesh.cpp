// A mesh file through assimp (scenes name meshes for occluders and backgrounds): the
// first input byte chooses the extension assimp goes by (obj, stl, ply, off); a mesh
// whose triangles index its vertices, or an InputError naming the file.
#include "fuzz_support.hpp"
#include "linksight/sim/mesh.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace linksight;
  if (size == 0) return 0;
  static const char* const kExt[] = {"obj", "stl", "ply", "off"};
  const auto path = fuzz::write_input(std::string("mesh.") + kExt[data[0] % 4], data + 1, size - 1);
  fuzz::expect_named(path.string(), [&] {
    const sim::TriangleMesh m = sim::load_mesh(path);
    const auto n = static_cast<int>(m.vertices.size());
    for (const auto& t : m.triangles)
      if (t.minCoeff() < 0 || t.maxCoeff() >= n) fuzz::finding("a triangle beyond the vertices");
  });
  return 0;
}
