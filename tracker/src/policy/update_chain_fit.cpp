// Update policy `chain-fit`: the nodes are a chain of components one pitch apart, fitted
// to the points by their distance to the component surfaces (chain_fit.hpp), not moved to
// the mean of their neighbourhood: ball centres, not the seen surface (issue 17). It fits
// a whole frame at once: from a constant-velocity prediction, holding the link's shape
// where the points say nothing, and re-initializing on evidence of loss.
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <string>

#include "linksight/tracker/chain_fit.hpp"
#include "../chain_pass.hpp"
#include "linksight/tracker/tracker.hpp"

namespace linksight {
namespace {

// The prediction's screen uses every kScreenStride-th point.
constexpr std::size_t kScreenStride = 8;
// A ball counts as seen well, for holding it (hold_seen), with at least this share of the
// median seen ball's inliers (a part-hidden ball's centre is less sure).
constexpr double kSeenShare = 0.5;
// slide_to_best's passes (its candidate shifts).
constexpr int kSlideSteps = kSlideCandidates;

class UpdateChainFit final : public UpdatePolicy {
 public:
  UpdateChainFit(const ComponentGeometry& geometry, const ChainFitParams& params,
                 const BasePriorParams& base, int threads)
      : geometry_(geometry), params_(params), threads_(threads), base_(base) {}

  // Run in a mode's iterations (a composition outside the table): one fit per call, from
  // the nodes as they are. The fit makes its own association (nearest component surface),
  // so the back end's is not read.
  double update(const PointsView& points, const Accumulation& /*acc*/, Backend& /*backend*/,
                Nodes& nodes) const override {
    ChainState chain = chain_from_nodes(nodes, geometry_);
    (void)fit_chain(points, chain, geometry_, params_, threads_);
    return replace(nodes, chain.nodes(geometry_.pitch));
  }

  [[nodiscard]] bool fits_frame() const override { return true; }

  FrameFit fit_frame(const PointsView& points, bool restarted, const InitPolicy& init,
                     const FrameExtras& extras, Backend& backend, Nodes& nodes,
                     std::vector<std::int64_t>& counts) override {
    passes_ = 0;
    const Eigen::Isometry3d* X_CB = extras.X_CB;
    depth_ = extras.depth;
    // The fits' passes on the back end's device, when it has one (the same bits).
    device_ = backend.chain_pass_device();
    if (device_ != nullptr) device_->set_chain_points(points);
    if (restarted) {
      last_.reset();
      before_.reset();
      last_X_CB_.reset();
    }
    Fit fit;
    if (restarted) {
      fit = fresh_fit(points, nodes, init, nullptr, X_CB);
    } else {
      const Eigen::Isometry3d T = predicted(points, nodes, X_CB);
      Nodes start = nodes;
      for (Eigen::Vector3d& q : start) q = T * q;
      fit = fit_from(points, start, false, anchor(X_CB, true));
    }
    // Loss (issue 17, part 5): the evidence is the fit's, not an empty neighbourhood. A
    // fresh start replaces the track only when it explains the points far better.
    bool reinit = false;
    if (!restarted && (static_cast<double>(fit.result.inliers) <
                           params_.misfit_inliers * static_cast<double>(last_inliers_) ||
                       fit.result.rms > params_.misfit_rms)) {
      Fit fresh = fresh_fit(points, init.init(points, static_cast<int>(nodes.size()), &nodes),
                            init, &nodes, X_CB);
      // Both under the fresh fit's (loose) anchor: the tracked fit's own is tighter, and
      // the same axis error would cost it more.
      const Anchor loose = anchor(X_CB, false);
      if (total(fresh, loose) < params_.reinit_gain * total(fit, loose)) {
        fit = std::move(fresh);
        reinit = true;
        last_.reset();
      }
    }
    (void)replace(nodes, fit.chain.nodes(geometry_.pitch));
    hold_seen(fit, X_CB, restarted || reinit);
    before_ = std::move(last_);
    last_ = nodes;
    last_X_CB_.reset();
    if (X_CB != nullptr) last_X_CB_ = *X_CB;
    last_inliers_ = fit.result.inliers;
    // A ball node counts the points of its component (ball and neck); the tip node has
    // no ball under it and counts none.
    counts.assign(nodes.size(), 0);
    std::copy(fit.result.counts.begin(), fit.result.counts.end(), counts.begin());
    device_ = nullptr;  // this frame's: not kept past it
    depth_ = nullptr;
    return {reinit, passes_};
  }

 private:
  // A ChainAnchor or none (not std::optional: GCC 12 warns, falsely, that the vector in it
  // may be used uninitialized when it is copied out of one).
  struct Anchor {
    bool given = false;
    ChainAnchor anchor;
    [[nodiscard]] const ChainAnchor* get() const { return given ? &anchor : nullptr; }
  };

  struct Fit {
    ChainState chain;
    ChainFitResult result;
  };

  // What a fit is chosen by: the points' robust cost and, with a base pose, the anchor's
  // (the one it was fitted under, or `under`: fits compare under one anchor).
  static double total(const Fit& f) { return f.result.cost + f.result.anchor_cost; }
  double total(const Fit& f, const Anchor& under) const {
    if (!under.given) return total(f);
    return f.result.cost + anchor_cost(f.chain, under.anchor, geometry_, params_);
  }

  // Where the base pose (issue 17, part 4) puts the first component: ball 0 at its
  // origin; component 0 along joint 0's bend as the last fit had it in the base frame
  // (the link holds its shape: σ the base's and bend_sigma together), or, with no fit to
  // take it from, along the base's +X (straight_sigma: loose, as joint 0 may be bent to
  // the cone limit, where a bend of 25° costs what about 12 points at the Huber threshold
  // do).
  Anchor anchor(const Eigen::Isometry3d* X_CB, bool tracking) const {
    Anchor out;
    if (X_CB == nullptr) return out;
    out.given = true;
    ChainAnchor& a = out.anchor;
    a.c0 = X_CB->translation();
    a.sigma_m = base_.sigma_m;
    Eigen::Vector3d bend_B = Eigen::Vector3d::UnitX();
    double bend_sigma = params_.straight_sigma;
    if (tracking && last_ && last_X_CB_) {
      const Eigen::Vector3d axis_C = ((*last_)[1] - (*last_)[0]).normalized();
      bend_B = last_X_CB_->linear().transpose() * axis_C;
      bend_sigma = params_.bend_sigma;
    }
    a.axis0 = (X_CB->linear() * bend_B).normalized();
    a.sigma_rad = std::hypot(base_.sigma_rad, bend_sigma);
    if (tracking) {
      a.held.resize(held_B_.size());
      for (std::size_t k = 0; k < held_B_.size(); ++k)
        if (held_B_[k]) a.held[k] = *X_CB * *held_B_[k];
      a.held_sigma_m = base_.sigma_m;
    }
    return out;
  }

  // Each ball the fit saw well (at least kSeenShare of the median seen ball's inliers),
  // in the base frame: where a hidden ball is held (ChainAnchor::held). Forgotten on a
  // fresh start and on a frame without a base pose.
  void hold_seen(const Fit& fit, const Eigen::Isometry3d* X_CB, bool fresh) {
    if (X_CB == nullptr || fresh) held_B_.clear();
    if (X_CB == nullptr) return;
    const std::vector<std::int64_t>& n = fit.result.counts;
    std::vector<std::int64_t> seen;
    for (const std::int64_t c : n)
      if (c > 0) seen.push_back(c);
    if (seen.empty()) return;
    std::nth_element(seen.begin(), seen.begin() + static_cast<std::ptrdiff_t>(seen.size() / 2),
                     seen.end());
    const double enough = kSeenShare * static_cast<double>(seen[seen.size() / 2]);
    held_B_.resize(n.size());
    const Eigen::Isometry3d X_BC = X_CB->inverse();
    for (std::size_t k = 0; k < n.size(); ++k)
      if (static_cast<double>(n[k]) >= enough)
        held_B_[k] = X_BC * fit.chain.centre(static_cast<int>(k), geometry_.pitch);
  }

  // The fit from `start`: after an initialization, slid along itself into the fit's reach
  // first (`slide`); else holding the start's shape (the last fit's, moved with the link).
  Fit fit_from(const PointsView& points, const Nodes& start, bool fresh,
               const Anchor& anchor, bool slide = true) {
    Fit f{chain_from_nodes(start, geometry_), {}};
    const ChainAnchor* a = anchor.get();
    if (!fresh) {
      const ChainState shape = f.chain;
      f.result = fit_chain(points, f.chain, geometry_, params_, threads_, &shape, a, device_,
                           depth_);
      passes_ += f.result.passes;
      return f;
    }
    if (slide) {
      f.chain = slide_to_best(points, f.chain, geometry_, params_, threads_);
      passes_ += kSlideSteps;
    }
    // No shape yet: a joint the points do not show (a tip neck turned away) comes out
    // straight, not wherever the initialization left it.
    ChainState straight = f.chain;
    std::fill(straight.axis.begin(), straight.axis.end(), Eigen::Vector3d::UnitZ());
    ChainFitParams loose = params_;
    loose.bend_sigma = params_.straight_sigma;
    f.result = fit_chain(points, f.chain, geometry_, loose, threads_, &straight, a, device_,
                         depth_);
    passes_ += f.result.passes;
    return f;
  }

  // With a base pose, a start's ball 0 is the end nearer the base: the base, not the
  // cloud's extent, says which end is which.
  static Nodes base_first(Nodes start, const Eigen::Isometry3d* X_CB) {
    if (X_CB != nullptr && (start.back() - X_CB->translation()).norm() <
                               (start.front() - X_CB->translation()).norm())
      std::reverse(start.begin(), start.end());
    return start;
  }

  // A fit from an initialization on every point (`start`) and, where the cloud has
  // clutter set apart from the link (a mug behind it bends the LSQ curve toward itself),
  // from one on its largest connected cluster: whichever explains all the points better.
  // Clusters alone would not do: a link that hides part of itself falls apart into them.
  // With a base pose, a third start competes: the chain straight out of the base, which
  // holds where the points show only part of the link (the base end hidden).
  // All under the loose anchor `a` (anchor(X_CB, false)).
  Fit fresh_start(const PointsView& points, const Nodes& start, const InitPolicy& init,
                  const Nodes* previous, const Eigen::Isometry3d* X_CB, const Anchor& a) {
    Fit best = fit_from(points, base_first(start, X_CB), true, a);
    if (X_CB != nullptr) {
      Nodes out(start.size());
      const Eigen::Vector3d x_C = X_CB->linear().col(0);
      for (std::size_t j = 0; j < out.size(); ++j)
        out[j] = X_CB->translation() + static_cast<double>(j) * geometry_.pitch * x_C;
      Fit other = fit_from(points, out, true, a, false);
      if (total(other) < total(best)) best = std::move(other);
    }
    // Cells of a neck radius: gaps under one cell are always bridged, and clutter 2√3
    // cells (24 mm) or more from the link never joins it.
    const std::vector<std::size_t> keep = largest_cluster(points, geometry_.neck_radius);
    if (keep.size() == points.size() || keep.size() < start.size()) return best;
    std::vector<float> x, y, z;
    for (const std::size_t i : keep) {
      x.push_back(points.x[i]);
      y.push_back(points.y[i]);
      z.push_back(points.z[i]);
    }
    const PointsView cluster{x, y, z};
    Fit other = fit_from(
        points, base_first(init.init(cluster, static_cast<int>(start.size()), previous), X_CB),
        true, a);
    return total(other) < total(best) ? other : best;
  }

  // A fresh fit can settle a whole component along the chain from where the link is,
  // every node about one pitch off, in a minimum the slide (half a pitch either way) does
  // not leave: seen on self_occlusion and on a C-bent link at 0.7 m under the two-scale
  // sr300 camera (45 mm from the first frame). The fit moved by one component each way
  // (the chain re-indexed: one end's node dropped, the other end continued straight) and
  // fitted again competes: whichever explains the points better (its total cost), the
  // unmoved one on a tie. Two more fits on a fresh start (the first frame, a restart, and
  // each re-initialization the loss test tries).
  Fit best_of_shifts(const PointsView& points, Fit best, const Anchor& a) {
    const Nodes nodes = best.chain.nodes(geometry_.pitch);
    const std::size_t n = nodes.size();
    // Toward the base end: a node before ball 0, the tip's dropped.
    Nodes back{Eigen::Vector3d(2 * nodes[0] - nodes[1])};
    back.insert(back.end(), nodes.begin(), nodes.end() - 1);
    // Toward the tip: ball 0's node dropped, one past the tip.
    Nodes ahead(nodes.begin() + 1, nodes.end());
    ahead.emplace_back(2 * nodes[n - 1] - nodes[n - 2]);
    for (const Nodes* moved : {&back, &ahead}) {
      Fit other = fit_from(points, *moved, true, a, false);
      if (total(other) < total(best)) best = std::move(other);
    }
    return best;
  }

  // The best fresh start (fresh_start), and of it moved by one component either way.
  Fit fresh_fit(const PointsView& points, const Nodes& start, const InitPolicy& init,
                const Nodes* previous, const Eigen::Isometry3d* X_CB) {
    const Anchor a = anchor(X_CB, false);
    return best_of_shifts(points, fresh_start(points, start, init, previous, X_CB, a), a);
  }

  // Constant velocity (issue 17, part 6): the previous frame's rigid move again (the best
  // rigid motion from the fit before it to the last fit), so that fast motion starts near
  // where the link is (few passes, no association across a component). Rigid, because the
  // link holds its shape unless pushed: a part hidden this frame moves with the whole,
  // where a per-node velocity would keep turning it on its own. A still link's fits differ
  // by their noise, which a rigid move extrapolates to millimetres at the tip: the points
  // (every kScreenStride-th) choose between the moved start and the last fit. With base
  // poses this frame and the last, the move is the base's since the last frame instead:
  // measured, not extrapolated (an error in the pose that stays put cancels in it).
  // Returns the move to start from (identity: from where the last fit left the link).
  Eigen::Isometry3d predicted(const PointsView& points, const Nodes& nodes,
                              const Eigen::Isometry3d* X_CB) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    if (X_CB != nullptr && last_X_CB_) {
      T = *X_CB * last_X_CB_->inverse();
    } else if (last_ && before_) {
      Eigen::Matrix3Xd from(3, nodes.size()), to(3, nodes.size());
      for (std::size_t j = 0; j < nodes.size(); ++j) {
        from.col(static_cast<Eigen::Index>(j)) = (*before_)[j];
        to.col(static_cast<Eigen::Index>(j)) = (*last_)[j];
      }
      T.matrix() = Eigen::umeyama(from, to, false);
    } else {
      return T;
    }
    Nodes moved = nodes;
    for (Eigen::Vector3d& q : moved) q = T * q;
    const double still =
        chain_cost(points, chain_from_nodes(nodes, geometry_), geometry_, params_, threads_,
                   kScreenStride);
    const double moving =
        chain_cost(points, chain_from_nodes(moved, geometry_), geometry_, params_, threads_,
                   kScreenStride);
    passes_ += 2;  // each 1/kScreenStride of one, counted whole
    return moving < still ? T : Eigen::Isometry3d::Identity();
  }

  static double replace(Nodes& nodes, const Nodes& fitted) {
    double max_move = 0.0;
    for (std::size_t j = 0; j < nodes.size(); ++j)
      max_move = std::max(max_move, (fitted[j] - nodes[j]).norm());
    nodes = fitted;
    return max_move;
  }

  ComponentGeometry geometry_;
  ChainFitParams params_;
  int threads_;
  BasePriorParams base_;
  std::optional<Nodes> last_, before_;  // the last two frames' fits, for the velocity
  // The base pose given with the last fit (none: not given).
  std::optional<Eigen::Isometry3d> last_X_CB_;
  // Each ball where it was last seen well, in the base frame (hold_seen).
  std::vector<std::optional<Eigen::Vector3d>> held_B_;
  std::size_t last_inliers_ = 0;        // the last fit's inliers, for the loss test
  int passes_ = 0;                      // this frame's passes over the points
  ChainPassDevice* device_ = nullptr;   // this frame's: where the fits' passes run
  const DepthView* depth_ = nullptr;    // this frame's depth image, or none
};

}  // namespace

std::unique_ptr<UpdatePolicy> make_update_chain_fit(const TrackerParams& params) {
  if (params.nodes != params.geometry.count + 1)
    throw std::invalid_argument("chain-fit: nodes = " + std::to_string(params.nodes) +
                                ": must be the geometry's count + 1 (" +
                                std::to_string(params.geometry.count + 1) +
                                "): a node per ball and the tip");
  // The fit's passes run on the OpenMP back end's threads (the same bits as serial, see
  // fit_chain), on the OpenCL back end's device (Backend::chain_pass_device; the same bits
  // again), and on one host thread otherwise, as do the screens and initializations.
  const int threads = params.backend == BackendKind::openmp ? params.threads : 1;
  return std::make_unique<UpdateChainFit>(params.geometry, params.policy.chain_fit,
                                          params.base_prior, threads);
}

}  // namespace linksight
