// Re-initialization trigger `never`: the nodes carry on from the previous frame.
#include "linksight/tracker/tracker.hpp"

namespace linksight {
namespace {

class ReinitNever final : public ReinitTrigger {
 public:
  int fired(const Accumulation& /*acc*/) const override { return -1; }
};

}  // namespace

std::unique_ptr<ReinitTrigger> make_reinit_never(const TrackerParams& /*params*/) {
  return std::make_unique<ReinitNever>();
}

}  // namespace linksight
