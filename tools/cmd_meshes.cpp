// linksight meshes: the component's triangle mesh for rendering and the simulator,
// generated from ComponentGeometry so it never drifts from the tracker's shape.
#include <filesystem>
#include <iostream>
#include <memory>
#include <sstream>

#include "commands.hpp"
#include "linksight/io/error.hpp"
#include "linksight/sim/mesh.hpp"

namespace linksight::cli {
namespace fs = std::filesystem;
namespace {

struct MeshesOptions {
  std::string out = "meshes";
  bool quiet = false;
};

int run_meshes(const MeshesOptions& o) {
  const ComponentGeometry g;
  const sim::TriangleMesh mesh = sim::component_mesh(g);
  std::error_code ec;
  fs::create_directories(o.out, ec);
  if (ec) throw io::InputError(o.out + ": cannot create output directory: " + ec.message());
  std::ostringstream header;
  header << "linksight component mesh: ball + neck capsule of one link component.\n"
         << "Units: metres. Frame K: origin at the ball centre, +Z toward the next ball.\n"
         << "Two closed, outward-oriented shells that overlap: a UV sphere (the ball) and a\n"
         << "capsule around (0,0,0)-(0,0,neck_length) (the neck).\n"
         << "From the default ComponentGeometry: ball_radius = " << g.ball_radius
         << " m, pitch = " << g.pitch << " m, neck_radius = " << g.neck_radius
         << " m, neck_length = " << g.neck_length << " m, count = " << g.count << ".\n"
         << "segments = 32; " << mesh.vertices.size() << " vertices, " << mesh.triangles.size()
         << " triangles.\n"
         << "Generated, do not edit. Regenerate: build/tools/linksight meshes --out meshes";
  const fs::path path = fs::path(o.out) / "component.obj";
  sim::write_obj(path, mesh, header.str());
  if (!o.quiet) {
    std::cout << "wrote " << path.string() << " (" << mesh.vertices.size() << " vertices, "
              << mesh.triangles.size() << " triangles)\n";
  }
  const struct {
    const char* file;
    sim::TriangleMesh mesh;
    const char* what;
  } props[] = {
      {"hand.obj", sim::hand_mesh(),
       "An occluder: a hand on a forearm (palm box, finger and thumb cylinders, forearm).\n"
       "Units: metres. Palm centred at the origin facing +-y, fingers along +z."},
      {"mug.obj", sim::mug_mesh(),
       "Clutter: a mug, radius 0.04 m, 0.10 m tall, standing on z = 0, handle on +x.\n"
       "Units: metres."},
  };
  for (const auto& prop : props) {
    const fs::path p = fs::path(o.out) / prop.file;
    sim::write_obj(p, prop.mesh,
                   std::string("linksight ") + prop.what +
                       "\nGenerated, do not edit. Regenerate: build/tools/linksight meshes --out meshes");
    if (!o.quiet) {
      std::cout << "wrote " << p.string() << " (" << prop.mesh.vertices.size() << " vertices, "
                << prop.mesh.triangles.size() << " triangles)\n";
    }
  }
  return kExitOk;
}

}  // namespace

Runner add_meshes(CLI::App& app) {
  auto o = std::make_shared<MeshesOptions>();
  app.add_option("--out", o->out, "output directory")->capture_default_str();
  app.add_flag("--quiet", o->quiet, "print nothing on success");
  return [o] { return run_meshes(*o); };
}

}  // namespace linksight::cli
