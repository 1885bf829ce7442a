// Output policy `surface`: the nodes as the SOM has them, on the seen surface.
#include "linksight/tracker/tracker.hpp"

namespace linksight {
namespace {

class OutputSurface final : public OutputPolicy {
 public:
  Nodes output(const Nodes& nodes) const override { return nodes; }
};

}  // namespace

std::unique_ptr<OutputPolicy> make_output_surface(const TrackerParams& /*params*/) {
  return std::make_unique<OutputSurface>();
}

}  // namespace linksight
