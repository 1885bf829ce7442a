#include "linksight/tracker/tracker.hpp"

#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "linksight/tracker/sdf.hpp"

namespace linksight {
void TrackerParams::validate() const {
  fields::check(*this, "tracker");
  if (nodes < 2 || nodes > kMaxNodes)
    fields::fail("tracker", "nodes", nodes, "must be in [2, " + std::to_string(kMaxNodes) + "]");
  policy.validate();
  base_prior.validate();
  geometry.validate();
  opencl.validate();
}

std::string_view to_string(InitReason r) {
  switch (r) {
    case InitReason::none:
      return "none";
    case InitReason::first_frame:
      return "first_frame";
    case InitReason::empty_neighbourhood:
      return "empty_neighbourhood";
    case InitReason::misfit:
      return "misfit";
  }
  return "unknown";
}
std::string_view to_string(LostReason r) {
  switch (r) {
    case LostReason::none:
      return "none";
    case LostReason::empty_cloud:
      return "empty_cloud";
    case LostReason::all_non_finite:
      return "all_non_finite";
    case LostReason::too_few_points:
      return "too_few_points";
    case LostReason::too_many_points:
      return "too_many_points";
  }
  return "unknown";
}

void DepthView::validate() const {
  if (width <= 0 || height <= 0 ||
      depth_m.size() != static_cast<std::size_t>(width) * static_cast<std::size_t>(height) ||
      !(fx > 0 && fy > 0 && std::isfinite(fx) && std::isfinite(fy) && std::isfinite(cx) &&
        std::isfinite(cy)))
    throw std::invalid_argument("depth image: needs width x height values (" +
                                std::to_string(width) + " x " + std::to_string(height) +
                                ", got " + std::to_string(depth_m.size()) +
                                ") and finite focal lengths > 0");
}

void BasePriorParams::validate() const { fields::check(*this, "base_prior"); }

void PolicyParams::validate() const {
  lsq_init.validate();
  som_init.validate();
  centre_offset.validate();
  chain_fit.validate();
}

struct Tracker::State {
  std::unique_ptr<Backend> backend;
  std::unique_ptr<InitPolicy> init;
  std::unique_ptr<UpdatePolicy> update;
  std::unique_ptr<ReinitTrigger> reinit;
  std::unique_ptr<OutputPolicy> output;
  std::vector<float> x, y, z;  // finite points of the current frame (SoA)
  bool has_association = false;
  std::vector<float> q;  // nodes as float xyz for the kernels
  Accumulation acc;
  Nodes nodes;  // previous frame's output
  bool has_previous = false;
};

Tracker::Tracker(const TrackerParams& params) : Tracker(params, params.mode.spec()) {}

Tracker::Tracker(const TrackerParams& params, const ModeSpec& mode) : params_(params) {
  params_.validate();
  state_ = std::make_unique<State>();
  state_->backend = make_backend(params_.backend, params_.threads, params_.opencl);
  state_->init = mode.init.make(params_);
  state_->update = mode.update.make(params_);
  state_->reinit = mode.reinit.make(params_);
  state_->output = mode.output.make(params_);
  state_->q.resize(3 * static_cast<std::size_t>(params_.nodes));
}
Tracker::~Tracker() = default;
Tracker::Tracker(Tracker&&) noexcept = default;
Tracker& Tracker::operator=(Tracker&&) noexcept = default;

void Tracker::reset() {
  state_->has_previous = false;
  state_->nodes.clear();
}

std::span<const std::int32_t> Tracker::last_association() const {
  if (!state_->has_association) return {};
  return state_->backend->association();
}

FrameResult Tracker::step(const Cloud& cloud, const Eigen::Isometry3d* X_CB,
                          const DepthView* depth) {
  if (depth != nullptr) depth->validate();
  if (X_CB != nullptr) {
    const Eigen::Matrix3d R = X_CB->linear();
    if (!X_CB->matrix().allFinite() ||
        !(R.transpose() * R - Eigen::Matrix3d::Identity()).isZero(1e-6) || R.determinant() < 0)
      throw std::invalid_argument("Tracker::step: the base pose X_CB is not a finite rigid pose");
  }
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  State& s = *state_;
  FrameResult r;
  const std::size_t n_total = cloud.size();
  s.x.resize(n_total);
  s.y.resize(n_total);
  s.z.resize(n_total);
  std::size_t n = 0;
  for (std::size_t i = 0; i < n_total; ++i) {
    const float px = cloud.xyz[3 * i], py = cloud.xyz[3 * i + 1], pz = cloud.xyz[3 * i + 2];
    // Beyond kMaxCoordinate the fixed-point sums could overflow.
    const PointCheck check = check_point(px, py, pz);
    if (check != PointCheck::kept) {
      ++(check == PointCheck::non_finite ? r.n_non_finite : r.n_out_of_range);
      continue;
    }
    s.x[n] = px;
    s.y[n] = py;
    s.z[n] = pz;
    ++n;
  }
  s.x.resize(n);
  s.y.resize(n);
  s.z.resize(n);
  r.n_points = n;
  const int m = params_.nodes;

  if (n_total == 0) {
    r.lost_reason = LostReason::empty_cloud;
  } else if (n == 0 && r.n_out_of_range == 0) {
    r.lost_reason = LostReason::all_non_finite;
  } else if (n < static_cast<std::size_t>(m)) {
    r.lost_reason = LostReason::too_few_points;
  } else if (n > kMaxPoints) {
    r.lost_reason = LostReason::too_many_points;
  }
  if (r.lost_reason != LostReason::none) {
    // A lost frame leaves the state alone: the next frame continues from the last output.
    r.lost = true;
    r.nodes = s.output->output(s.nodes);
    r.counts.assign(static_cast<std::size_t>(m), 0);
    r.sdf_error = std::numeric_limits<double>::quiet_NaN();
    s.has_association = false;
    r.time_s = std::chrono::duration<double>(Clock::now() - t0).count();
    return r;
  }

  const PointsView view{{s.x.data(), n}, {s.y.data(), n}, {s.z.data(), n}};
  bool initialized_now = false;
  if (!s.has_previous) {
    s.nodes = s.init->init(view, m, nullptr);
    r.init_reason = InitReason::first_frame;
    initialized_now = true;
  }

  if (s.update->fits_frame()) {
    const FrameFit fit = s.update->fit_frame(view, initialized_now, *s.init,
                                                  FrameExtras{X_CB, depth}, *s.backend,
                                                  s.nodes, s.acc.count);
    if (fit.reinit) {
      r.reinit = true;
      r.init_reason = InitReason::misfit;
    }
    s.has_association = false;
    r.iterations = fit.passes;
    return finish(r, t0);
  }

  s.backend->set_points(view);  // one upload per frame (a whole-frame fit needs none)

  // Algorithm 1, lines 8-21. A re-initialization restarts the iteration count once, so
  // the output is always SOM-refined; a second empty neighbourhood in the same frame
  // leaves that node where it is (LSQ on the same cloud would give the same nodes).
  int remaining = params_.iterations;
  while (remaining-- > 0) {
    for (int j = 0; j < m; ++j) {
      for (int a = 0; a < 3; ++a) s.q[3 * j + a] = static_cast<float>(s.nodes[j][a]);
    }
    s.backend->associate(s.q, s.acc);  // Eq. (11)
    s.has_association = true;
    ++r.iterations;
    const int fired = initialized_now ? -1 : s.reinit->fired(s.acc);
    if (fired >= 0) {
      const Nodes previous = s.nodes;
      s.nodes = s.init->init(view, m, &previous);  // Sec. IV.C
      r.reinit = true;
      r.init_reason = InitReason::empty_neighbourhood;
      r.reinit_node = fired;
      initialized_now = true;
      remaining = params_.iterations;
      continue;
    }
    const double max_move = s.update->update(view, s.acc, *s.backend, s.nodes);
    if (params_.tolerance > 0.0 && max_move <= params_.tolerance) break;
  }
  return finish(r, t0);
}

FrameResult& Tracker::finish(FrameResult& r, std::chrono::steady_clock::time_point t0) {
  State& s = *state_;
  s.has_previous = true;
  r.nodes = s.output->output(s.nodes);
  r.counts = s.acc.count;
  r.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.device_time_s = s.backend->device_seconds();
  const PointsView view{{s.x.data(), s.x.size()}, {s.y.data(), s.y.size()}, {s.z.data(), s.z.size()}};
  r.sdf_error = params_.compute_sdf ? sdf_error(view, r.nodes, params_.geometry)
                                    : std::numeric_limits<double>::quiet_NaN();
  return r;
}

FrameFit UpdatePolicy::fit_frame(const PointsView& /*points*/, bool /*restarted*/,
                                 const InitPolicy& /*init*/, const FrameExtras& /*extras*/,
                                 Backend& /*backend*/, Nodes& /*nodes*/,
                                 std::vector<std::int64_t>& /*counts*/) {
  throw std::logic_error("UpdatePolicy::fit_frame: this policy updates per iteration");
}

}  // namespace linksight
