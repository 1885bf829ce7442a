#pragma once
// chain-fit's search for each point's component (chain_fit.cpp), in float and two vectors
// of points at a time, as paper mode's association (kernels.hpp) is. The answer is defined as the
// argmin over every component of the float distance to its surface (ball of radius r at
// the centre ∪ capsule of radius r_n along [0, L] of the axis), ties to the lower index.
// The device (chain.cl) computes exactly that, by brute force; the CPU skips components
// that provably cannot win (below), which gives the same answer. The winner's residual,
// normal and Jacobian are then computed in double, from the point and that component
// alone, as a pass that reuses an association does.

#include <cstddef>
#include <cstdint>
#include <vector>

namespace linksight::detail {

/// The chain's components for the search, in float: centres and axes [m], radii and neck
/// length [m], and `reach`, the farthest any component's surface lies from its centre.
struct ChainSearchFrames {
  std::vector<float> cx, cy, cz, ax, ay, az;
  float r = 0, rn = 0, L = 0, reach = 0;
};

// A component whose centre is farther from p than (the nearest centre's ball distance +
// reach + this) cannot be nearest: its surface is at least |p - c_k| - reach away. The
// margin covers the float rounding of both sides (a few ulp of a 100 m coordinate is
// under 2e-5 m) with room to spare, so a skipped component's float distance always
// exceeds the winner's and skipping never changes the answer.
inline constexpr float kChainSearchMargin = 1e-3f;  // [m]

/// Every `stride`-th point of [begin, end): its component (the argmin above) into out[i]
/// (i the point's index; the others are left alone). In float, two vectors of points at a
/// time: SSE (4 lanes) on baseline x86-64, AVX2 (8 lanes) where the CPU has it, picked at
/// run time; the same IEEE operations on every lane, so the same answers. A short last group
/// is padded with its last point.
void chain_search_range(const float* x, const float* y, const float* z, std::size_t begin,
                        std::size_t end, std::size_t stride, const ChainSearchFrames& f,
                        std::int16_t* out);

/// The same with a chosen width: 4 lanes (two SSE vectors at a time) or 8 (two AVX2
/// vectors where the CPU has AVX2, else the same 8 lanes in baseline code). For tests:
/// every width gives the same answers.
void chain_search_range_lanes(int lanes, const float* x, const float* y, const float* z,
                              std::size_t begin, std::size_t end, std::size_t stride,
                              const ChainSearchFrames& f, std::int16_t* out);

}  // namespace linksight::detail
