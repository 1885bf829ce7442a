// Update policy `chain-fit`: the nodes are a chain of components one pitch apart, fitted
// to the points by their distance to the component surfaces (chain_fit.hpp), not moved to
// the mean of their neighbourhood: ball centres, not the seen surface (issue 17).
#include <algorithm>
#include <stdexcept>
#include <string>

#include "linksight/tracker/chain_fit.hpp"
#include "linksight/tracker/tracker.hpp"

namespace linksight {
namespace {

class UpdateChainFit final : public UpdatePolicy {
 public:
  UpdateChainFit(const ComponentGeometry& geometry, const ChainFitParams& params)
      : geometry_(geometry), params_(params) {}
  // The fit makes its own association (nearest component surface), so the back end's is
  // not read: every back end gives the serial result.
  double update(const PointsView& points, const Accumulation& /*acc*/, Backend& /*backend*/,
                Nodes& nodes) const override {
    ChainState chain = chain_from_nodes(nodes, geometry_);
    (void)fit_chain(points, chain, geometry_, params_);
    const Nodes fitted = chain.nodes(geometry_.pitch);
    double max_move = 0.0;
    for (std::size_t j = 0; j < nodes.size(); ++j)
      max_move = std::max(max_move, (fitted[j] - nodes[j]).norm());
    nodes = fitted;
    return max_move;
  }

 private:
  ComponentGeometry geometry_;
  ChainFitParams params_;
};

}  // namespace

std::unique_ptr<UpdatePolicy> make_update_chain_fit(const TrackerParams& params) {
  if (params.nodes != params.geometry.count + 1)
    throw std::invalid_argument("chain-fit: nodes = " + std::to_string(params.nodes) +
                                ": must be the geometry's count + 1 (" +
                                std::to_string(params.geometry.count + 1) +
                                "): a node per ball and the tip");
  return std::make_unique<UpdateChainFit>(params.geometry, params.policy.chain_fit);
}

}  // namespace linksight
