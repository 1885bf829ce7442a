// intrinsics.json: intrinsics that pass validate(), or an InputError naming the file.
#include "fuzz_support.hpp"
#include "linksight/io/intrinsics.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace linksight;
  const auto path = fuzz::write_input("intrinsics.json", data, size);
  fuzz::expect_named(path.string(), [&] {
    const io::Intrinsics K = io::read_intrinsics(path);
    try {
      K.validate();
    } catch (const std::exception& e) {
      fuzz::finding(std::string("read intrinsics that validate() refuses: ") + e.what());
    }
  });
  return 0;
}
