// Output policy `centre-offset`: each node moved from the seen surface toward the ball
// centre by a constant share of the radius along its viewing ray (not in the paper).
#include <cmath>
#include <stdexcept>
#include <string>

#include "linksight/tracker/tracker.hpp"

namespace linksight {

void CentreOffsetParams::validate() const { fields::check(*this, "centre_offset"); }

namespace {

class OutputCentreOffset final : public OutputPolicy {
 public:
  explicit OutputCentreOffset(double offset) : offset_(offset) {}
  Nodes output(const Nodes& nodes) const override {
    Nodes out = nodes;
    for (Eigen::Vector3d& q : out) {
      const double d = q.norm();  // the camera sits at the origin of the cloud's frame
      if (d > 0) q *= (d + offset_) / d;
    }
    return out;
  }

 private:
  double offset_;  // [m]
};

}  // namespace

std::unique_ptr<OutputPolicy> make_output_centre_offset(const TrackerParams& params) {
  return std::make_unique<OutputCentreOffset>(params.policy.centre_offset.fraction *
                                              params.geometry.ball_radius);
}

}  // namespace linksight
