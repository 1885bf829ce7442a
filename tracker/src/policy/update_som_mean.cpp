// Update policy `som-mean`: each node moves to the mean of its neighbourhood (Eq. 12).
#include <algorithm>

#include "linksight/tracker/tracker.hpp"

namespace linksight {
namespace {

class UpdateSomMean final : public UpdatePolicy {
 public:
  double update(const PointsView& /*points*/, const Accumulation& acc, Backend& /*backend*/,
                Nodes& nodes) const override {
    double max_move = 0.0;
    for (std::size_t j = 0; j < nodes.size(); ++j) {
      // A node that owns no points stays where it is.
      if (acc.count[j] == 0) continue;
      const Eigen::Vector3d updated = acc.mean(static_cast<int>(j));  // Eq. (12)
      max_move = std::max(max_move, (updated - nodes[j]).norm());
      nodes[j] = updated;
    }
    return max_move;
  }
};

}  // namespace

std::unique_ptr<UpdatePolicy> make_update_som_mean(const TrackerParams& /*params*/) {
  return std::make_unique<UpdateSomMean>();
}

}  // namespace linksight
