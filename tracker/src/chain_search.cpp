#include "chain_search.hpp"

#include <cstring>
#include <limits>

// The 32-byte vector helpers below are always inlined, never called across an ABI boundary:
// GCC's note that their calling convention differs with and without AVX does not apply.
#pragma GCC diagnostic ignored "-Wpsabi"

namespace linksight::detail {
namespace {

// W float lanes: 4 (one SSE vector, baseline x86-64; NEON on arm64) or 8 (one AVX2 vector).
// Every lane computes its own point with the same IEEE operations, so a point's answer does
// not depend on the width or on which points share its vector.
template <int W>
struct Lanes;
template <>
struct Lanes<4> {
  using F = float __attribute__((vector_size(16)));
  using I = std::int32_t __attribute__((vector_size(16)));
};
template <>
struct Lanes<8> {
  using F = float __attribute__((vector_size(32)));
  using I = std::int32_t __attribute__((vector_size(32)));
};

// Select by mask arithmetic: GCC scalarizes the vector ?: without SSE4.1.
template <class F, class I>
[[gnu::always_inline]] inline F select(const I& mask, const F& a, const F& b) {
  return (F)(((I)a & mask) | ((I)b & ~mask));
}

// Correctly rounded, lane by lane, as OpenCL's sqrt under
// -cl-fp32-correctly-rounded-divide-sqrt. With -fno-math-errno (the tracker's build) GCC
// turns the lanes into one sqrtps / vsqrtps.
template <int W, class F>
[[gnu::always_inline]] inline F vsqrt(const F& v) {
  F r;
  for (int l = 0; l < W; ++l) r[l] = __builtin_sqrtf(v[l]);
  return r;
}

template <int W, class I>
[[gnu::always_inline]] inline bool any(const I& m) {
  std::uint64_t w[W / 2];
  std::memcpy(w, &m, sizeof m);
  std::uint64_t o = 0;
  for (int l = 0; l < W / 2; ++l) o |= w[l];
  return o != 0;
}

template <class F>
[[gnu::always_inline]] inline F centre_d2(const F& px, const F& py, const F& pz,
                                          const ChainSearchFrames& f, std::size_t k) {
  const F dx = px - f.cx[k], dy = py - f.cy[k], dz = pz - f.cz[k];
  return dx * dx + dy * dy + dz * dz;
}

// Component k's float distance to W points: the nearer of ball and neck, in chain.cl's
// distance_f's operations and order.
template <int W, class F>
[[gnu::always_inline]] inline F distance(const F& px, const F& py, const F& pz,
                                         const ChainSearchFrames& f, std::size_t k) {
  using I = typename Lanes<W>::I;
  const F dx = px - f.cx[k], dy = py - f.cy[k], dz = pz - f.cz[k];
  const F ball = vsqrt<W>(dx * dx + dy * dy + dz * dz) - f.r;
  const F t = dx * f.ax[k] + dy * f.ay[k] + dz * f.az[k];
  const F zero = {};
  const F lo = select<F, I>(t < zero, zero, t);  // std::clamp(t, 0, L)
  const F s = select<F, I>(f.L < lo, zero + f.L, lo);
  const F ex = dx - s * f.ax[k], ey = dy - s * f.ay[k], ez = dz - s * f.az[k];
  const F neck = vsqrt<W>(ex * ex + ey * ey + ez * ez) - f.rn;
  return select<F, I>(neck < ball, neck, ball);
}

// P vectors of W points (independent chains of operations, which the core overlaps): each
// point's component into out[0..P W).
template <int W, int P>
[[gnu::always_inline]] inline void search(const float* x, const float* y, const float* z,
                                          const ChainSearchFrames& f, std::int16_t* out) {
  using F = typename Lanes<W>::F;
  using I = typename Lanes<W>::I;
  F px[P], py[P], pz[P];
  for (int p = 0; p < P; ++p) {
    std::memcpy(&px[p], x + p * W, sizeof(F));
    std::memcpy(&py[p], y + p * W, sizeof(F));
    std::memcpy(&pz[p], z + p * W, sizeof(F));
  }
  const std::size_t count = f.cx.size();
  const F zero = {};
  const F inf = zero + std::numeric_limits<float>::infinity();
  // The nearest centre bounds the winner's distance from above (its ball's distance).
  F d2min[P], bound[P], best[P];
  I j[P];
  for (int p = 0; p < P; ++p) d2min[p] = inf;
  for (std::size_t k = 0; k < count; ++k)
    for (int p = 0; p < P; ++p) {
      const F d2 = centre_d2(px[p], py[p], pz[p], f, k);
      d2min[p] = select<F, I>(d2 < d2min[p], d2, d2min[p]);
    }
  for (int p = 0; p < P; ++p) {
    const F u = vsqrt<W>(d2min[p]) + (f.reach - f.r + kChainSearchMargin);
    bound[p] = u * u;
    best[p] = inf;
    j[p] = I{};
  }
  for (std::size_t k = 0; k < count; ++k) {
    // The same squared distances as above, recomputed rather than kept per component.
    I near = {};
    for (int p = 0; p < P; ++p) near |= centre_d2(px[p], py[p], pz[p], f, k) < bound[p];
    if (!any<W>(near)) continue;
    // Ascending k and a strict comparison: ties go to the lower index, as on the device.
    for (int p = 0; p < P; ++p) {
      const F e = distance<W>(px[p], py[p], pz[p], f, k);
      const I c = e < best[p];
      best[p] = select<F, I>(c, e, best[p]);
      j[p] = (c & static_cast<std::int32_t>(k)) | (j[p] & ~c);
    }
  }
  for (int p = 0; p < P; ++p)
    for (int l = 0; l < W; ++l) out[p * W + l] = static_cast<std::int16_t>(j[p][l]);
}

template <int W, int P>
[[gnu::always_inline]] inline void search_range(const float* x, const float* y, const float* z,
                                                std::size_t begin, std::size_t end,
                                                std::size_t stride, const ChainSearchFrames& f,
                                                std::int16_t* out) {
  std::size_t i = begin;
  if (stride == 1)  // contiguous: straight from the arrays
    for (; i + W * P <= end; i += W * P) search<W, P>(x + i, y + i, z + i, f, out + i);
  float bx[W * P], by[W * P], bz[W * P];
  std::int16_t kw[W * P];
  std::size_t idx[W * P];
  int fill = 0;
  for (; i < end; i += stride) {
    bx[fill] = x[i];
    by[fill] = y[i];
    bz[fill] = z[i];
    idx[fill] = i;
    if (++fill < W * P && i + stride < end) continue;
    for (int l = fill; l < W * P; ++l) {  // pad a short last group with its last point
      bx[l] = bx[fill - 1];
      by[l] = by[fill - 1];
      bz[l] = bz[fill - 1];
    }
    search<W, P>(bx, by, bz, f, kw);
    for (int l = 0; l < fill; ++l) out[idx[l]] = kw[l];
    fill = 0;
  }
}

// Whether the CPU has AVX2, found once.
bool has_avx2() {
#if defined(__GNUC__) && defined(__x86_64__)
  static const bool avx2 = [] {
    __builtin_cpu_init();  // idempotent; needed should a static initializer get here first
    return __builtin_cpu_supports("avx2") != 0;
  }();
  return avx2;
#else
  return false;
#endif
}

#if defined(__GNUC__) && defined(__x86_64__)
// The same code with 8 lanes, compiled for AVX2 (everything above is inlined into it).
__attribute__((target("avx2"))) void search_range_avx2(const float* x, const float* y,
                                                       const float* z, std::size_t begin,
                                                       std::size_t end, std::size_t stride,
                                                       const ChainSearchFrames& f,
                                                       std::int16_t* out) {
  search_range<8, 2>(x, y, z, begin, end, stride, f, out);
}
#endif

}  // namespace

void chain_search_range_lanes(int lanes, const float* x, const float* y, const float* z,
                              std::size_t begin, std::size_t end, std::size_t stride,
                              const ChainSearchFrames& f, std::int16_t* out) {
  if (lanes == 8) {
#if defined(__GNUC__) && defined(__x86_64__)
    if (has_avx2()) {
      search_range_avx2(x, y, z, begin, end, stride, f, out);
      return;
    }
#endif
    search_range<8, 2>(x, y, z, begin, end, stride, f, out);  // the same lanes, baseline code
    return;
  }
  search_range<4, 2>(x, y, z, begin, end, stride, f, out);
}

void chain_search_range(const float* x, const float* y, const float* z, std::size_t begin,
                        std::size_t end, std::size_t stride, const ChainSearchFrames& f,
                        std::int16_t* out) {
  chain_search_range_lanes(has_avx2() ? 8 : 4, x, y, z, begin, end, stride, f, out);
}

}  // namespace linksight::detail
