// A sweep grid file: axes that make a valid sweep spec (or a spec refusal naming the
// axis, std::invalid_argument as the CLI reports it), or an InputError naming the file.
#include "fuzz_support.hpp"
#include "linksight/sim/sweep.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace linksight;
  const auto path = fuzz::write_input("grid.yaml", data, size);
  fuzz::expect_named(path.string(), [&] {
    sim::SweepSpec spec;
    spec.scene = "scene.yaml";
    spec.axes = sim::read_grid(path);
    if (spec.axes.empty()) fuzz::finding("a grid of no axes read without an error");
    try {
      spec.validate();
      if (spec.cells() == 0 || spec.cells() > sim::kMaxSweepCells)
        fuzz::finding("a valid grid of " + std::to_string(spec.cells()) + " cells");
    } catch (const std::invalid_argument& e) {
      if (std::string(e.what()).rfind("sweep: ", 0) != 0)
        fuzz::finding(std::string("a spec refusal that does not say sweep: ") + e.what());
      // Not an InputError, so not made printable by its constructor: the echo rule must
      // hold at each key and value the refusal shows.
      fuzz::expect_printable(e.what());
    }
  });
  return 0;
}
