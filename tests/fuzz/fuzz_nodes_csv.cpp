// An estimate's nodes.csv (score) and a base-prior CSV (track --base-prior): tables of
// the asked size with finite values, or an InputError naming the file.
#include <cmath>

#include "fuzz_support.hpp"
#include "linksight/io/base_pose.hpp"
#include "linksight/io/nodes_csv.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace linksight;
  const auto path = fuzz::write_input("table.csv", data, size);
  for (const std::size_t frames : {std::size_t{0}, std::size_t{3}}) {
    fuzz::expect_named(path.string(), [&] {
      const auto table = io::read_nodes_csv(path, frames, frames == 0 ? 0 : 12);
      if (frames != 0 && table.size() != frames) fuzz::finding("a table of the wrong size");
      for (const auto& f : table) {
        if (!f) continue;
        if (frames != 0 && f->size() != 12) fuzz::finding("a frame of the wrong node count");
        for (const auto& q : *f)
          if (!q.allFinite()) fuzz::finding("a non-finite node");
      }
    });
  }
  fuzz::expect_named(path.string(), [&] {
    const auto poses = io::read_base_poses(path, 3);
    if (poses.size() != 3) fuzz::finding("base poses of the wrong count");
    for (const auto& X : poses)
      if (!X.matrix().allFinite() ||
          std::abs(X.linear().determinant() - 1.0) > 1e-6)
        fuzz::finding("a base pose that is not a finite rigid transform");
  });
  return 0;
}
