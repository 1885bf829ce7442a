// Init policy `som`: the accelerated-SOM baseline's straight-line or random-sample init.
#include "linksight/tracker/tracker.hpp"

namespace linksight {
namespace {

class InitSom final : public InitPolicy {
 public:
  explicit InitSom(const SomInitParams& params) : params_(params) {}
  // The baseline keeps no order across frames: the previous nodes play no part.
  Nodes init(const PointsView& points, int n_nodes, const Nodes* /*previous*/) const override {
    return som_init(points, n_nodes, params_.method, params_.seed);
  }

 private:
  SomInitParams params_;
};

}  // namespace

std::unique_ptr<InitPolicy> make_init_som(const TrackerParams& params) {
  return std::make_unique<InitSom>(params.policy.som_init);
}

}  // namespace linksight
