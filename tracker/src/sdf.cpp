#include "linksight/tracker/sdf.hpp"

#include <cmath>
#include <limits>

#include "kernels.hpp"

namespace linksight {

double sdf_error(const PointsView& points, const Nodes& nodes, const ComponentGeometry& geometry) {
  const std::size_t n = points.size();
  if (n == 0 || nodes.size() < 2) return std::numeric_limits<double>::quiet_NaN();
  const std::vector<ComponentFrame> frames = frames_from_nodes(nodes);
  std::vector<float> q(3 * nodes.size());
  for (std::size_t j = 0; j < nodes.size(); ++j) {
    for (int a = 0; a < 3; ++a) q[3 * j + a] = static_cast<float>(nodes[j][a]);
  }
  const int m = static_cast<int>(nodes.size());
  std::int32_t assoc[detail::kBlock];
  double total = 0.0;
  for (std::size_t b = 0; b < n; b += detail::kBlock) {
    const std::size_t len = std::min(detail::kBlock, n - b);
    // Eq. (13): the same association as the SOM step.
    detail::associate_block(points.x.data() + b, points.y.data() + b, points.z.data() + b, len,
                            q.data(), m, assoc);
    for (std::size_t i = 0; i < len; ++i) {
      // The last node only orients frame M-1 (Eq. 1), so its points belong to frame M-1.
      const std::size_t k =
          std::min<std::size_t>(static_cast<std::size_t>(assoc[i]), frames.size() - 1);
      const Eigen::Vector3d p_C(points.x[b + i], points.y[b + i], points.z[b + i]);
      const Eigen::Vector3d p_K = frames[k].X_CK.inverse() * p_C;  // Eq. (14)
      total += std::abs(geometry.sdf(p_K));                        // Eq. (15)
    }
  }
  return total / static_cast<double>(n);  // Eq. (16)
}

}  // namespace linksight
