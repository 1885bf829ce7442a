// Re-initialization trigger `empty-neighbourhood`: a node that owns no point (Sec. IV.C).
#include <algorithm>

#include "linksight/tracker/tracker.hpp"

namespace linksight {
namespace {

class ReinitEmptyNeighbourhood final : public ReinitTrigger {
 public:
  int fired(const Accumulation& acc) const override {
    const auto empty = std::find(acc.count.begin(), acc.count.end(), 0);
    return empty == acc.count.end() ? -1 : static_cast<int>(empty - acc.count.begin());
  }
};

}  // namespace

std::unique_ptr<ReinitTrigger> make_reinit_empty_neighbourhood(const TrackerParams& /*params*/) {
  return std::make_unique<ReinitEmptyNeighbourhood>();
}

}  // namespace linksight
