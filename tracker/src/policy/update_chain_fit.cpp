// Update policy `chain-fit`: the nodes are a chain of components one pitch apart, fitted
// to the points by their distance to the component surfaces (chain_fit.hpp), not moved to
// the mean of their neighbourhood: ball centres, not the seen surface (issue 17). It fits
// a whole frame at once: from a constant-velocity prediction, holding the link's shape
// where the points say nothing, and re-initializing on evidence of loss.
#include <Eigen/Geometry>

#include <algorithm>
#include <optional>
#include <stdexcept>
#include <string>

#include "linksight/tracker/chain_fit.hpp"
#include "linksight/tracker/tracker.hpp"

namespace linksight {
namespace {

// The prediction's screen uses every kScreenStride-th point.
constexpr std::size_t kScreenStride = 8;
// slide_to_best's passes (its candidate shifts).
constexpr int kSlideSteps = kSlideCandidates;

class UpdateChainFit final : public UpdatePolicy {
 public:
  UpdateChainFit(const ComponentGeometry& geometry, const ChainFitParams& params, int threads)
      : geometry_(geometry), params_(params), threads_(threads) {}

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
                     Nodes& nodes, std::vector<std::int64_t>& counts) override {
    passes_ = 0;
    if (restarted) {
      last_.reset();
      before_.reset();
    }
    Fit fit = restarted ? fresh_fit(points, nodes, init, nullptr)
                        : fit_from(points, predicted(points, nodes), false);
    // Loss (issue 17, part 5): the evidence is the fit's, not an empty neighbourhood. A
    // fresh start replaces the track only when it explains the points far better.
    bool reinit = false;
    if (!restarted && (static_cast<double>(fit.result.inliers) <
                           params_.misfit_inliers * static_cast<double>(last_inliers_) ||
                       fit.result.rms > params_.misfit_rms)) {
      Fit fresh = fresh_fit(points, init.init(points, static_cast<int>(nodes.size()), &nodes),
                            init, &nodes);
      if (fresh.result.cost < params_.reinit_gain * fit.result.cost) {
        fit = std::move(fresh);
        reinit = true;
        last_.reset();
      }
    }
    (void)replace(nodes, fit.chain.nodes(geometry_.pitch));
    before_ = std::move(last_);
    last_ = nodes;
    last_inliers_ = fit.result.inliers;
    // A ball node counts the points of its component (ball and neck); the tip node has
    // no ball under it and counts none.
    counts.assign(nodes.size(), 0);
    std::copy(fit.result.counts.begin(), fit.result.counts.end(), counts.begin());
    return {reinit, passes_};
  }

 private:
  struct Fit {
    ChainState chain;
    ChainFitResult result;
  };

  // The fit from `start`: after an initialization, slid along itself into the fit's reach
  // first; else holding the start's shape (the last fit's, moved with the link).
  Fit fit_from(const PointsView& points, const Nodes& start, bool fresh) {
    Fit f{chain_from_nodes(start, geometry_), {}};
    if (!fresh) {
      const ChainState shape = f.chain;
      f.result = fit_chain(points, f.chain, geometry_, params_, threads_, &shape);
      passes_ += f.result.passes;
      return f;
    }
    f.chain = slide_to_best(points, f.chain, geometry_, params_, threads_);
    // No shape yet: a joint the points do not show (a tip neck turned away) comes out
    // straight, not wherever the initialization left it.
    ChainState straight = f.chain;
    std::fill(straight.axis.begin(), straight.axis.end(), Eigen::Vector3d::UnitZ());
    ChainFitParams loose = params_;
    loose.bend_sigma = params_.straight_sigma;
    f.result = fit_chain(points, f.chain, geometry_, loose, threads_, &straight);
    passes_ += f.result.passes + kSlideSteps;
    return f;
  }

  // A fit from an initialization on every point (`start`) and, where the cloud has
  // clutter set apart from the link (a mug behind it bends the LSQ curve toward itself),
  // from one on its largest connected cluster: whichever explains all the points better.
  // Clusters alone would not do: a link that hides part of itself falls apart into them.
  Fit fresh_fit(const PointsView& points, const Nodes& start, const InitPolicy& init,
                const Nodes* previous) {
    Fit best = fit_from(points, start, true);
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
    Fit other = fit_from(points, init.init(cluster, static_cast<int>(start.size()), previous), true);
    return other.result.cost < best.result.cost ? other : best;
  }

  // Constant velocity (issue 17, part 6): the previous frame's rigid move again (the best
  // rigid motion from the fit before it to the last fit), so that fast motion starts near
  // where the link is (few passes, no association across a component). Rigid, because the
  // link holds its shape unless pushed: a part hidden this frame moves with the whole,
  // where a per-node velocity would keep turning it on its own. A still link's fits differ
  // by their noise, which a rigid move extrapolates to millimetres at the tip: the points
  // (every kScreenStride-th) choose between the moved start and the last fit.
  Nodes predicted(const PointsView& points, const Nodes& nodes) {
    if (!last_ || !before_) return nodes;
    Eigen::Matrix3Xd from(3, nodes.size()), to(3, nodes.size());
    for (std::size_t j = 0; j < nodes.size(); ++j) {
      from.col(static_cast<Eigen::Index>(j)) = (*before_)[j];
      to.col(static_cast<Eigen::Index>(j)) = (*last_)[j];
    }
    const Eigen::Matrix4d T = Eigen::umeyama(from, to, false);
    Nodes moved = nodes;
    for (Eigen::Vector3d& q : moved) q = T.topLeftCorner<3, 3>() * q + T.topRightCorner<3, 1>();
    const double still =
        chain_cost(points, chain_from_nodes(nodes, geometry_), geometry_, params_, threads_,
                   kScreenStride);
    const double moving =
        chain_cost(points, chain_from_nodes(moved, geometry_), geometry_, params_, threads_,
                   kScreenStride);
    passes_ += 2;  // each 1/kScreenStride of one, counted whole
    return moving < still ? moved : nodes;
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
  std::optional<Nodes> last_, before_;  // the last two frames' fits, for the velocity
  std::size_t last_inliers_ = 0;        // the last fit's inliers, for the loss test
  int passes_ = 0;                      // this frame's passes over the points
};

}  // namespace

std::unique_ptr<UpdatePolicy> make_update_chain_fit(const TrackerParams& params) {
  if (params.nodes != params.geometry.count + 1)
    throw std::invalid_argument("chain-fit: nodes = " + std::to_string(params.nodes) +
                                ": must be the geometry's count + 1 (" +
                                std::to_string(params.geometry.count + 1) +
                                "): a node per ball and the tip");
  // The fit's passes run on the OpenMP back end's threads (the same bits as serial, see
  // fit_chain); serial and OpenCL fit on one host thread.
  const int threads = params.backend == BackendKind::openmp ? params.threads : 1;
  return std::make_unique<UpdateChainFit>(params.geometry, params.policy.chain_fit, threads);
}

}  // namespace linksight
