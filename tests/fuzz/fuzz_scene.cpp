// A scene file with --set overrides (run, render, sweep): the input's first line, when it
// starts with "#set ", holds overrides separated by ';' (what --set takes), the rest is
// the scene. A scene that loads passes its own checks (its resolved YAML, every value
// written out, loads again); anything else is an InputError naming the file.
#include <sstream>
#include <vector>

#include "fuzz_support.hpp"
#include "linksight/sim/scene.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace linksight;
  std::string text(reinterpret_cast<const char*>(data), size);
  std::vector<std::string> overrides;
  if (text.rfind("#set ", 0) == 0) {
    const std::size_t eol = text.find('\n');
    std::stringstream sets(text.substr(5, eol == std::string::npos ? std::string::npos : eol - 5));
    for (std::string o; std::getline(sets, o, ';');) overrides.push_back(o);
  }
  const auto path = fuzz::write_input("scene.yaml", data, size);
  fuzz::expect_named(path.string(), [&] {
    const std::string resolved = sim::resolved_scene_yaml(path, overrides);
    const auto again = fuzz::write_input(
        "resolved.yaml", reinterpret_cast<const std::uint8_t*>(resolved.data()), resolved.size());
    try {
      (void)sim::load_scene(again);
    } catch (const std::exception& e) {
      fuzz::finding(std::string("a scene that loads resolves to YAML that does not: ") + e.what());
    }
  });
  return 0;
}
