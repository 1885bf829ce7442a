#include "linksight/sim/trajectory.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace linksight::sim {

void Sweep::validate() const {
  fields::check(*this, "sweep");
  if (!(axis_B.norm() >= 1e-9)) throw fields::FieldError("axis", "[...]", "must not be zero", "sweep");
}

BaseTrajectory::BaseTrajectory(std::vector<Waypoint> waypoints, std::vector<Sweep> sweeps)
    : waypoints_(std::move(waypoints)), sweeps_(std::move(sweeps)) {
  const auto item = [](const char* what, std::size_t i, auto&& validate) {
    try {
      validate();
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("BaseTrajectory: " + std::string(what) + " " +
                                  std::to_string(i) + ": " + e.what());
    }
  };
  for (std::size_t i = 0; i < waypoints_.size(); ++i) {
    item("waypoint", i, [&] { waypoints_[i].validate(); });
    if (i > 0 && !(waypoints_[i].t > waypoints_[i - 1].t)) {
      throw std::invalid_argument("BaseTrajectory: waypoint " + std::to_string(i) + " time " +
                                  format_shortest(waypoints_[i].t) +
                                  " s must be later than the one before");
    }
  }
  for (std::size_t i = 0; i < sweeps_.size(); ++i) item("sweep", i, [&] { sweeps_[i].validate(); });
}

Eigen::Isometry3d BaseTrajectory::pose(double t) const {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  if (!waypoints_.empty()) {
    if (t <= waypoints_.front().t) {
      X = waypoints_.front().X_WB;
    } else if (t >= waypoints_.back().t) {
      X = waypoints_.back().X_WB;
    } else {
      std::size_t i = 1;
      while (waypoints_[i].t < t) ++i;
      const Waypoint &a = waypoints_[i - 1], &b = waypoints_[i];
      const double s = (t - a.t) / (b.t - a.t);
      const Eigen::Quaterniond qa(a.X_WB.rotation()), qb(b.X_WB.rotation());
      X.linear() = qa.slerp(s, qb).toRotationMatrix();
      X.translation() = (1 - s) * a.X_WB.translation() + s * b.X_WB.translation();
    }
  }
  for (const Sweep& s : sweeps_) {
    const double w = std::sin(2 * std::numbers::pi * s.frequency * t + s.phase);
    X.translation() += w * s.offset_W;
    X.linear() =
        X.linear() * Eigen::AngleAxisd(s.amplitude * w, s.axis_B.normalized()).toRotationMatrix();
  }
  return X;
}

}  // namespace linksight::sim
