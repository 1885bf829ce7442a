#include "linksight/tracker/chain_state.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace linksight {

Eigen::Vector3d ChainState::centre(int k, double pitch) const {
  Eigen::Vector3d c = c0;
  // Summed from the base, the same way for every k, so a node does not depend on which
  // node was asked for first.
  for (int j = 0; j < k; ++j) c += pitch * axis[static_cast<std::size_t>(j)];
  return c;
}

Nodes ChainState::nodes(double pitch) const {
  Nodes out;
  out.reserve(axis.size() + 1);
  Eigen::Vector3d c = c0;
  out.push_back(c);
  for (const Eigen::Vector3d& a : axis) {
    c += pitch * a;
    out.push_back(c);
  }
  return out;
}

double ChainState::max_bend() const {
  double worst = 0;
  for (std::size_t k = 1; k < axis.size(); ++k)
    worst = std::max(worst, std::acos(std::clamp(axis[k - 1].dot(axis[k]), -1.0, 1.0)));
  return worst;
}

ChainState chain_from_nodes(const Nodes& nodes, const ComponentGeometry& geometry) {
  const auto count = static_cast<std::size_t>(geometry.count);
  if (nodes.size() != count + 1)
    throw std::invalid_argument("chain_from_nodes: " + std::to_string(nodes.size()) +
                                " nodes, expected count + 1 = " + std::to_string(count + 1));
  for (const Eigen::Vector3d& p : nodes)
    if (!p.allFinite()) throw std::invalid_argument("chain_from_nodes: a node is not finite");
  ChainState s;
  s.c0 = nodes[0];
  s.axis.reserve(count);
  Eigen::Vector3d previous = Eigen::Vector3d::UnitZ();
  for (std::size_t k = 0; k < count; ++k) {
    const Eigen::Vector3d d = nodes[k + 1] - nodes[k];
    const double n = d.norm();
    previous = n > 0 ? Eigen::Vector3d(d / n) : previous;
    s.axis.push_back(previous);
  }
  return s;
}

int limit_bends(ChainState& chain, double cone_limit) {
  if (!(cone_limit >= 0 && cone_limit <= 3.14159265358979323846))
    throw std::invalid_argument("limit_bends: cone_limit must be in [0, pi] rad");
  int bent = 0;
  const double cos_limit = std::cos(cone_limit);
  for (std::size_t k = 1; k < chain.axis.size(); ++k) {
    const Eigen::Vector3d& a = chain.axis[k - 1];
    Eigen::Vector3d& b = chain.axis[k];
    if (a.dot(b) >= cos_limit) continue;
    // The unit vector normal to a in the plane of a and b, toward b.
    Eigen::Vector3d n = b - a.dot(b) * a;
    if (n.norm() < 1e-12) {
      // b opposite a: any plane holds a; take the one toward the next axis if there is one.
      const Eigen::Vector3d hint =
          k + 1 < chain.axis.size() ? chain.axis[k + 1] : Eigen::Vector3d(a.unitOrthogonal());
      n = hint - a.dot(hint) * a;
      if (n.norm() < 1e-12) n = a.unitOrthogonal();
    }
    n.normalize();
    b = std::cos(cone_limit) * a + std::sin(cone_limit) * n;
    ++bent;
  }
  return bent;
}

}  // namespace linksight
