#pragma once
// Per-pixel random draws shared by the sensor's stages (the cast's lateral jitter, the
// noise model): counter-based, so a (key, stream) pair always gives the same number,
// whichever thread asks, and the images do not depend on the thread count.

#include <cstddef>
#include <cmath>
#include <cstdint>

#include "linksight/tracker/seed.hpp"

namespace linksight::sim::detail {

// The draws' streams per pixel key.
enum Stream : std::uint64_t {
  kJitter = 0, kAxial = 2, kEdge = 4, kFlying = 5, kMix = 6, kAxialLow = 7, kAxialLowGrid = 8
};

// The seed of frame `frame` of the sensor's draws from the run's `seed`.
inline std::uint64_t sensor_frame_seed(std::uint64_t seed, std::uint64_t frame) {
  return derive_seed(derive_seed(seed, "sensor"), frame);
}

inline double uniform(std::uint64_t key, std::uint64_t stream) {
  return unit_interval(mix64(key + stream * 0xD1B54A32D192ED03ull));
}
// N(0, 1) by the inverse CDF (Acklam's rational approximation, relative error 1.2e-9):
// one uniform per draw and no transcendental call in the central 95%.
inline double inverse_normal_cdf(double p) {
  static constexpr double a[] = {-3.969683028665376e+01, 2.209460984245205e+02,
                                 -2.759285104469687e+02, 1.383577518672690e+02,
                                 -3.066479806614716e+01, 2.506628277459239e+00};
  static constexpr double b[] = {-5.447609879822406e+01, 1.615858368580409e+02,
                                 -1.556989798598866e+02, 6.680131188771972e+01,
                                 -1.328068155288572e+01};
  static constexpr double c[] = {-7.784894002430293e-03, -3.223964580411365e-01,
                                 -2.400758277161838e+00, -2.549732539343734e+00,
                                 4.374664141464968e+00,  2.938163982698783e+00};
  static constexpr double d[] = {7.784695709041462e-03, 3.224671290700398e-01,
                                 2.445134137142996e+00, 3.754408661907416e+00};
  constexpr double low = 0.02425;
  if (p < low || p > 1 - low) {
    const double q = std::sqrt(-2 * std::log(p < low ? p : 1 - p));
    const double x = (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
                     ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1);
    return p < low ? x : -x;
  }
  const double q = p - 0.5, r = q * q;
  return (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
         (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1);
}
// The inverse CDF tabulated at 4096 equal steps of p; linear interpolation inside, the
// exact rational form in the outer two bins (|x| > 3.5). Interpolation error < 1e-4.
struct NormalTable {
  static constexpr int kBins = 4096;
  double x[kBins + 1];
  NormalTable() {
    for (int i = 1; i < kBins; ++i) x[i] = inverse_normal_cdf(static_cast<double>(i) / kBins);
    x[0] = x[kBins] = 0.0;  // unused: the outer bins use the exact form
  }
};
inline const NormalTable kNormalTable;

// N(0, 1) from 32 random bits: the table's bin is the top 12 bits, the position inside it
// the other 20. Bits are the centre of one of 2^32 equal bins: p is never 0 or 1, and the
// extreme draw is 6.3 sigma.
inline double normal32(std::uint32_t bits) {
  static_assert(NormalTable::kBins == 1 << 12);
  const int i = static_cast<int>(bits >> 20);
  if (i == 0 || i == NormalTable::kBins - 1)
    return inverse_normal_cdf((static_cast<double>(bits) + 0.5) * 0x1.0p-32);
  const double f = (static_cast<double>(bits & 0xFFFFFu) + 0.5) * 0x1.0p-20;
  return kNormalTable.x[i] + f * (kNormalTable.x[i + 1] - kNormalTable.x[i]);
}
inline double normal(std::uint64_t key, std::uint64_t stream) {
  return normal32(static_cast<std::uint32_t>(mix64(key + stream * 0xD1B54A32D192ED03ull) >> 32));
}
// The largest |normal32|: the draw from bits 0.
inline const double kMaxNormal32 = -inverse_normal_cdf(0.5 * 0x1.0p-32);
// Pixel `pix`'s key: the splitmix64 sequence of the frame's seed, indexed by pixel.
inline std::uint64_t pixel_key(std::uint64_t frame_seed, std::size_t pix) {
  return mix64(frame_seed + (pix + 1) * 0x9E3779B97F4A7C15ull);
}

}  // namespace linksight::sim::detail
