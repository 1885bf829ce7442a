// Init policy `lsq-centred`: the LSQ initialization, each node then moved from the seen
// surface toward the ball centres by kCentreOffset of the radius along its viewing ray.
// Only a start: a model fit from it has the surface points within reach of the balls it
// fits (from the surface itself, 10 mm in front of the centres, many points lie deep inside
// the model's balls, beyond the fit's max_distance, and the first frames fit slowly).
#include "linksight/tracker/tracker.hpp"

namespace linksight {
namespace {

class InitLsqCentred final : public InitPolicy {
 public:
  InitLsqCentred(const InitParams& params, double offset) : params_(params), offset_(offset) {}
  Nodes init(const PointsView& points, int n_nodes, const Nodes* previous) const override {
    Nodes nodes = lsq_init(points, n_nodes, params_, previous);
    for (Eigen::Vector3d& q : nodes) {
      const double d = q.norm();  // the camera sits at the origin of the cloud's frame
      if (d > 0) q *= (d + offset_) / d;
    }
    return nodes;
  }

 private:
  InitParams params_;
  double offset_;  // [m]
};

}  // namespace

std::unique_ptr<InitPolicy> make_init_lsq_centred(const TrackerParams& params) {
  return std::make_unique<InitLsqCentred>(params.policy.lsq_init,
                                          kCentreOffset * params.geometry.ball_radius);
}

}  // namespace linksight
