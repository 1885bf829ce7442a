// A 16-bit depth PNG and its deprojection with the shipped SR305 intrinsics (track's
// path): an image of width x height pixels within the pixel limit, a cloud of finite
// points, or an InputError naming the file.
#include <cmath>

#include "fuzz_support.hpp"
#include "linksight/io/depth_png.hpp"
#include "linksight/io/frames.hpp"
#include "linksight/io/intrinsics.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace linksight;
  const auto path = fuzz::write_input("in.png", data, size);
  fuzz::expect_named(path.string(), [&] {
    const io::DepthImage img = io::read_depth_png(path);
    const long long px = static_cast<long long>(img.width) * img.height;
    if (img.width <= 0 || img.height <= 0 || px > io::kMaxDepthPngPixels ||
        static_cast<long long>(img.data.size()) != px)
      fuzz::finding("an image of " + std::to_string(img.width) + "x" + std::to_string(img.height) +
                    " with " + std::to_string(img.data.size()) + " pixels");
  });
  static const io::Intrinsics K = io::read_intrinsics(LINKSIGHT_FUZZ_INTRINSICS);
  fuzz::expect_named(path.string(), [&] {
    const Cloud c = io::load_frame(path, &K);
    for (const float v : c.xyz)
      if (!std::isfinite(v)) fuzz::finding("a non-finite point from a depth image");
  });
  return 0;
}
