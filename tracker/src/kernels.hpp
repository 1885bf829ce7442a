#pragma once
// Point kernels shared by every CPU back end and the SDF metric, so that they all
// make the same float comparisons and therefore the same associations.

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>

namespace linksight::detail {

inline constexpr std::size_t kBlock = 256;

// Eq. (11): nearest node by squared Euclidean distance, ties to the lowest index.
// Eight points at a time as two 4-wide vectors (SSE2 on baseline x86-64, NEON on arm64),
// nodes in the inner loop; the scalar tail does the same float operations in the same
// order, so a point gets the same answer whichever path takes it.
inline void associate_block(const float* x, const float* y, const float* z, std::size_t n,
                            const float* q, int m, std::int32_t* out) {
  using v4f = float __attribute__((vector_size(16)));
  using v4i = std::int32_t __attribute__((vector_size(16)));
  // Select by mask arithmetic: GCC scalarizes the vector ?: without SSE4.1.
  auto select = [](v4i mask, v4f a, v4f b) { return (v4f)(((v4i)a & mask) | ((v4i)b & ~mask)); };
  constexpr std::size_t W = 8;
  const float inf = std::numeric_limits<float>::infinity();
  std::size_t i = 0;
  for (; i + W <= n; i += W) {
    v4f px0, py0, pz0, px1, py1, pz1;
    std::memcpy(&px0, x + i, 16);
    std::memcpy(&px1, x + i + 4, 16);
    std::memcpy(&py0, y + i, 16);
    std::memcpy(&py1, y + i + 4, 16);
    std::memcpy(&pz0, z + i, 16);
    std::memcpy(&pz1, z + i + 4, 16);
    v4f best0 = {inf, inf, inf, inf}, best1 = best0;
    v4i j0 = {}, j1 = {};
    for (int j = 0; j < m; ++j) {
      const float qx = q[3 * j], qy = q[3 * j + 1], qz = q[3 * j + 2];
      const v4f dx0 = px0 - qx, dy0 = py0 - qy, dz0 = pz0 - qz;
      const v4f dx1 = px1 - qx, dy1 = py1 - qy, dz1 = pz1 - qz;
      const v4f d0 = dx0 * dx0 + dy0 * dy0 + dz0 * dz0;
      const v4f d1 = dx1 * dx1 + dy1 * dy1 + dz1 * dz1;
      const v4i c0 = d0 < best0, c1 = d1 < best1;
      best0 = select(c0, d0, best0);
      best1 = select(c1, d1, best1);
      j0 = (c0 & j) | (j0 & ~c0);
      j1 = (c1 & j) | (j1 & ~c1);
    }
    std::memcpy(out + i, &j0, 16);
    std::memcpy(out + i + 4, &j1, 16);
  }
  for (; i < n; ++i) {
    float best = std::numeric_limits<float>::infinity();
    std::int32_t best_j = 0;
    for (int j = 0; j < m; ++j) {
      const float dx = x[i] - q[3 * j], dy = y[i] - q[3 * j + 1], dz = z[i] - q[3 * j + 2];
      const float d = dx * dx + dy * dy + dz * dz;
      if (d < best) {
        best = d;
        best_j = j;
      }
    }
    out[i] = best_j;
  }
}

// Fixed point of a coordinate, exactly as the OpenCL kernels' convert_long_rte(v * 2^32f):
// the product is exact, and adding and subtracting 1.5 * 2^52 rounds it to the nearest
// integer, ties to even, for |v * 2^32| < 2^51 (any |v| <= kMaxCoordinate).
inline std::int64_t to_fixed(float v) {
  constexpr double kRound = 6755399441055744.0;  // 1.5 * 2^52
  const double t = static_cast<double>(v) * 4294967296.0;
  return static_cast<std::int64_t>((t + kRound) - kRound);
}

// Associates [begin, end) and adds fixed-point Σx, Σy, Σz and counts (Eq. 12 inputs).
inline void associate_range(const float* x, const float* y, const float* z, std::size_t begin,
                            std::size_t end, const float* q, int m, std::int32_t* assoc,
                            std::int64_t* sum, std::int64_t* count) {
  for (std::size_t b = begin; b < end; b += kBlock) {
    const std::size_t n = (end - b < kBlock) ? end - b : kBlock;
    associate_block(x + b, y + b, z + b, n, q, m, assoc + b);
    for (std::size_t i = b; i < b + n; ++i) {
      const std::int32_t j = assoc[i];
      sum[3 * j] += to_fixed(x[i]);
      sum[3 * j + 1] += to_fixed(y[i]);
      sum[3 * j + 2] += to_fixed(z[i]);
      ++count[j];
    }
  }
}

}  // namespace linksight::detail
