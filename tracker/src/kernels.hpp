#pragma once
// Point kernels shared by every CPU back end and the SDF metric, so that they all
// make the same float comparisons and therefore the same associations.

#include <cstddef>
#include <cstdint>
#include <limits>

namespace linksight::detail {

inline constexpr std::size_t kBlock = 256;

// Eq. (11): nearest node by squared Euclidean distance, ties to the lowest index.
// Nodes outer, points inner, so the compiler vectorizes over points.
inline void associate_block(const float* x, const float* y, const float* z, std::size_t n,
                            const float* q, int m, std::int32_t* out) {
  float best[kBlock];
  for (std::size_t i = 0; i < n; ++i) {
    best[i] = std::numeric_limits<float>::infinity();
    out[i] = 0;
  }
  for (int j = 0; j < m; ++j) {
    const float qx = q[3 * j], qy = q[3 * j + 1], qz = q[3 * j + 2];
    for (std::size_t i = 0; i < n; ++i) {
      const float dx = x[i] - qx, dy = y[i] - qy, dz = z[i] - qz;
      const float d = dx * dx + dy * dy + dz * dz;
      const bool closer = d < best[i];
      best[i] = closer ? d : best[i];
      out[i] = closer ? j : out[i];
    }
  }
}

// Associates [begin, end) and adds Σx, Σy, Σz and counts into sum/count (Eq. 12 inputs).
inline void associate_range(const float* x, const float* y, const float* z, std::size_t begin,
                            std::size_t end, const float* q, int m, std::int32_t* assoc,
                            double* sum, std::int64_t* count) {
  for (std::size_t b = begin; b < end; b += kBlock) {
    const std::size_t n = (end - b < kBlock) ? end - b : kBlock;
    associate_block(x + b, y + b, z + b, n, q, m, assoc + b);
    for (std::size_t i = b; i < b + n; ++i) {
      const std::int32_t j = assoc[i];
      sum[3 * j] += x[i];
      sum[3 * j + 1] += y[i];
      sum[3 * j + 2] += z[i];
      ++count[j];
    }
  }
}

}  // namespace linksight::detail
