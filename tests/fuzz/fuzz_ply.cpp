// PLY (ASCII and binary little-endian): a cloud whose size matches its array, or an
// InputError naming the file.
#include "fuzz_support.hpp"
#include "linksight/io/ply.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace linksight;
  const auto path = fuzz::write_input("in.ply", data, size);
  fuzz::expect_named(path.string(), [&] {
    const Cloud c = io::read_ply(path);
    if (c.xyz.size() % 3 != 0) fuzz::finding("a cloud of " + std::to_string(c.xyz.size()) + " floats");
    if (c.size() > size) fuzz::finding("more points than the file has bytes");
  });
  return 0;
}
