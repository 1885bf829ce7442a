// Output policy `centres`: the nodes as a model fit has them, the ball centres and the
// tip node (no correction: there is no surface bias to take off).
#include "linksight/tracker/tracker.hpp"

namespace linksight {
namespace {

class OutputCentres final : public OutputPolicy {
 public:
  Nodes output(const Nodes& nodes) const override { return nodes; }
};

}  // namespace

std::unique_ptr<OutputPolicy> make_output_centres(const TrackerParams& /*params*/) {
  return std::make_unique<OutputCentres>();
}

}  // namespace linksight
