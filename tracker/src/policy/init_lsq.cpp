// Init policy `lsq`: the paper's LSQ polynomial initialization (Sec. IV.A, Eqs. 9-10).
#include "linksight/tracker/tracker.hpp"

namespace linksight {
namespace {

class InitLsq final : public InitPolicy {
 public:
  explicit InitLsq(const InitParams& params) : params_(params) {}
  Nodes init(const PointsView& points, int n_nodes, const Nodes* previous) const override {
    // On re-initialization the previous nodes orient the new ones (Sec. IV.C).
    return lsq_init(points, n_nodes, params_, previous);
  }

 private:
  InitParams params_;
};

}  // namespace

std::unique_ptr<InitPolicy> make_init_lsq(const TrackerParams& params) {
  return std::make_unique<InitLsq>(params.policy.lsq_init);
}

}  // namespace linksight
