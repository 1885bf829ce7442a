#include "linksight/sim/sensor_noise.hpp"

#include <omp.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

#include "pixel_draws.hpp"

namespace linksight::sim {
namespace {

using detail::kAxial;
using detail::kAxialLow;
using detail::kAxialLowGrid;
using detail::kEdge;
using detail::kFlying;
using detail::kMix;
using detail::normal;
using detail::pixel_key;
using detail::inverse_normal_cdf;
using detail::uniform;

// The pixel-scale depth factor's largest table step [m]: linear between its entries,
// within 1e-6 (relative) of the power law for the preset's power over 0.5-0.9 m, about
// 1e-5 for a power of 4 from 0.2 m.
constexpr double kPixelFactorStep_m = 0.0005;
// The angle term's table (SensorNoise::angle_power_) is made for a cap of at least this
// [rad].
constexpr double kMinAngleTableCap = 1e-6;

// The taps f(i), i = -R..R, scaled to sum k^2 = 1: one 1-D pass keeps unit white noise at
// unit variance (at the image border the kernel is cut and the variance a little lower).
template <class F>
std::vector<float> unit_variance_taps(int R, F f) {
  std::vector<double> g(static_cast<std::size_t>(2 * R + 1));
  double sum2 = 0;
  for (int i = -R; i <= R; ++i) {
    g[static_cast<std::size_t>(i + R)] = f(i);
    sum2 += g[static_cast<std::size_t>(i + R)] * g[static_cast<std::size_t>(i + R)];
  }
  std::vector<float> k(g.size());
  for (std::size_t i = 0; i < g.size(); ++i) k[i] = static_cast<float>(g[i] / std::sqrt(sum2));
  return k;
}

// A Gaussian of standard deviation s [px], cut at 3 s.
std::vector<float> unit_variance_gaussian(double s) {
  return unit_variance_taps(static_cast<int>(std::ceil(3 * s)),
                            [s](int i) { return std::exp(-0.5 * i * i / (s * s)); });
}

// The Matern-5/2 field's 1-D filter for range r [px]: the filter whose autocorrelation is
// the covariance's, i.e. the square root of its spectrum (a + w^2)^-3 (a = 5 / r^2), which
// is the Matern-1 function x K_1(x), x = sqrt(5) |i| / r (1 at i = 0); cut at 3 r, where
// it has fallen below 1e-2 and its autocorrelation is within 0.005 of the Matern's at every
// lag (r >= 3 px).
std::vector<float> unit_variance_matern52(double r) {
  const double alpha = std::sqrt(5.0) / r;
  return unit_variance_taps(static_cast<int>(std::ceil(3 * r)), [alpha](int i) {
    const double x = alpha * std::abs(i);
    return i == 0 ? 1.0 : x * std::cyl_bessel_k(1.0, x);
  });
}

// The separable blur of a w x h row-major field, one pass each way. Every output sums
// kernel[i + R] * input over the taps inside the field, i ascending from 0, the same float
// operations in the same order whatever the thread count; the loops run along rows, so
// the compiler vectorizes them and the column pass reads whole rows.
void blur_rows(const std::vector<float>& src, std::vector<float>& dst, int w, int h,
               const std::vector<float>& kernel, int threads) {
  const int R = static_cast<int>(kernel.size() / 2);
#pragma omp parallel for schedule(static) num_threads(threads)
  for (int y = 0; y < h; ++y) {
    const float* in = src.data() + static_cast<std::size_t>(y) * w;
    float* out = dst.data() + static_cast<std::size_t>(y) * w;
    std::fill(out, out + w, 0.0F);
    for (int i = -R; i <= R; ++i) {
      const float k = kernel[static_cast<std::size_t>(i + R)];
      // The bounds computed once: in the loop's condition they keep it from vectorizing.
      const int x0 = std::max(0, -i), x1 = std::min(w, w - i);
      for (int x = x0; x < x1; ++x) out[x] += k * in[x + i];
    }
  }
}
void blur_columns(const std::vector<float>& src, std::vector<float>& dst, int w, int h,
                  const std::vector<float>& kernel, int threads) {
  const int R = static_cast<int>(kernel.size() / 2);
#pragma omp parallel for schedule(static) num_threads(threads)
  for (int y = 0; y < h; ++y) {
    float* out = dst.data() + static_cast<std::size_t>(y) * w;
    std::fill(out, out + w, 0.0F);
    for (int i = std::max(-R, -y); i <= std::min(R, h - 1 - y); ++i) {
      const float k = kernel[static_cast<std::size_t>(i + R)];
      const float* in = src.data() + static_cast<std::size_t>(y + i) * w;
      for (int x = 0; x < w; ++x) out[x] += k * in[x];
    }
  }
}

}  // namespace

SensorNoise::SensorNoise(const NoiseParams& noise, const CameraParams& camera)
    : noise_(noise), camera_(camera) {
  noise.validate();
  camera.validate();
  const AxialNoise& ax = noise.axial;
  if (ax.rows_px() > 0) {
    const auto taps = ax.kernel == AxialKernel::matern52 ? unit_variance_matern52 : unit_variance_gaussian;
    rows_kernel_ = taps(ax.rows_px());
    cols_kernel_ = taps(ax.cols_px());
  }
  if (ax.low_share > 0) {  // in grid steps where the field is drawn on a grid
    low_rows_kernel_ = unit_variance_gaussian(ax.low_rows_px / ax.low_stride_px);
    low_cols_kernel_ = unit_variance_gaussian(ax.low_cols_px / ax.low_stride_px);
  }
  const bool split = ax.low_share > 0 && !ax.low_angle_term;
  if (ax.pixel_depth_power != 0 && split) {
    // Steps of at most kPixelFactorStep_m that end exactly at the range's end.
    // (For the preset's 0.4 m the step is 0.5 mm to the bit, as the table was first made.)
    const double span = ax.pixel_depth_max_m - ax.pixel_depth_min_m;
    const auto steps = static_cast<std::size_t>(std::ceil(span / kPixelFactorStep_m));
    pixel_factor_ = LerpTable(ax.pixel_depth_min_m, ax.pixel_depth_max_m, steps,
                              [&](double z) { return ax.pixel_depth_factor(z); });
  }
  // Under a microradian of cap the table's step would be subnormal: std::pow does it.
  if (ax.angle_power != 2 && ax.theta_cap >= kMinAngleTableCap && split)
    angle_power_ = LerpTable(0, ax.theta_cap, kAngleTableSteps,
                             [&](double th) { return ax.point(0, th).q_power; });
  // edges.drop_steps in the PNG's units: the least d with d unit > jump, found with the
  // same double product as the rule, so the two agree for every d.
  const double jump = noise.edges.jump, unit = camera.intrinsics.depth_scale;
  step_units_ = std::max(1, static_cast<int>(jump / unit) - 1);
  while (!(step_units_ * unit > jump)) ++step_units_;
  while (step_units_ > 1 && (step_units_ - 1) * unit > jump) --step_units_;
  none_.assign(static_cast<std::size_t>(camera.intrinsics.width), 0);
}

void SensorNoise::apply(const NoiseInput& in, std::uint64_t seed, std::uint64_t frame, int threads,
                        io::DepthImage& depth, std::vector<float>& depth_m) {
  const PixelBox all{0, in.width - 1, 0, in.height - 1};
  apply(in, seed, frame, all, all, threads, depth, depth_m);
}

void SensorNoise::apply(const NoiseInput& in, std::uint64_t seed, std::uint64_t frame,
                        const PixelBox& noisy_asked, const PixelBox& hits, int threads,
                        io::DepthImage& depth, std::vector<float>& depth_m) {
  const io::Intrinsics& K = camera_.intrinsics;
  const NoiseParams& noise = noise_;
  const int W = K.width, H = K.height;
  const std::size_t n = static_cast<std::size_t>(W) * H;
  if (in.width != W || in.height != H)
    throw std::invalid_argument("sensor noise: a " + std::to_string(in.width) + "x" +
                                std::to_string(in.height) + " input for a " + std::to_string(W) +
                                "x" + std::to_string(H) + " camera");
  for (const std::size_t size : {in.depth_m.size(), in.incidence.size(), in.cos_camera.size(),
                                 in.cos_projector.size(), in.reflectance.size(), in.lit.size()}) {
    if (size != n)
      throw std::invalid_argument("sensor noise: an input image of " + std::to_string(size) +
                                  " values for " + std::to_string(n) + " pixels");
  }
  if (threads <= 0) threads = omp_get_max_threads();
  // Only the image's pixels can be written: a box reaching beyond it is cut to it.
  const PixelBox noisy{std::max(0, noisy_asked.u0), std::min(W - 1, noisy_asked.u1),
                       std::max(0, noisy_asked.v0), std::min(H - 1, noisy_asked.v1)};
  const std::uint64_t frame_seed = detail::sensor_frame_seed(seed, frame);
  depth.width = W;
  depth.height = H;
  depth.data.assign(n, 0);
  depth_m.assign(n, 0.0F);
  hole_.assign(n, 0);
  if (noise.dropouts.enabled && noise.dropouts.hole_rate > 0) {
    std::uint64_t state = derive_seed(frame_seed, "holes");
    auto next = [&] { return unit_interval(splitmix64(state)); };
    // Poisson count: Knuth's product method, or a rounded normal for large rates.
    int holes = 0;
    const double rate = noise.dropouts.hole_rate;
    if (rate < 30) {
      const double limit = std::exp(-rate);
      for (double prod = next(); prod > limit; prod *= next()) ++holes;
    } else {
      const double u1 = next();
      const double g = standard_normal(u1, next());
      holes = std::max(0, static_cast<int>(std::lround(rate + std::sqrt(rate) * g)));
    }
    // Sizes log-normal: ln A ~ N(ln median, s^2) with s from the 90th percentile.
    const double mu = std::log(noise.dropouts.hole_median_px);
    const double s_ln = std::log(noise.dropouts.hole_p90_px / noise.dropouts.hole_median_px) /
                        1.2815515655446004;  // the standard normal's 90th percentile
    std::vector<int>& blob = blob_;
    blob_stamp_.resize(n, 0);  // pixel k is in the current blob when its stamp is blob_id
    for (int h = 0; h < holes; ++h) {
      const int u0 = std::min(W - 1, static_cast<int>(next() * W));
      const int v0 = std::min(H - 1, static_cast<int>(next() * H));
      const double g = inverse_normal_cdf(std::clamp(next(), 1e-12, 1 - 1e-12));
      const int area = static_cast<int>(std::clamp(std::lround(std::exp(mu + s_ln * g)), 1L,
                                                   static_cast<long>(Dropouts::kMaxHolePx)));
      // Grown one 4-neighbour of a random member at a time: a compact, ragged blob.
      if (++blob_id_ == 0) {  // the ids wrapped: forget every stamp
        std::fill(blob_stamp_.begin(), blob_stamp_.end(), 0U);
        blob_id_ = 1;
      }
      const std::uint32_t id = blob_id_;
      blob.assign(1, v0 * W + u0);
      blob_stamp_[static_cast<std::size_t>(blob[0])] = id;
      for (int tries = 0; static_cast<int>(blob.size()) < area && tries < 50 * area; ++tries) {
        const int k = blob[std::min(blob.size() - 1, static_cast<std::size_t>(next() * blob.size()))];
        const int d = std::min(3, static_cast<int>(next() * 4));
        const int u = k % W + (d == 0) - (d == 1), v = k / W + (d == 2) - (d == 3);
        if (u < 0 || u >= W || v < 0 || v >= H) continue;
        const std::size_t kk = static_cast<std::size_t>(v) * W + u;
        if (blob_stamp_[kk] == id) continue;
        blob_stamp_[kk] = id;
        blob.push_back(v * W + u);
      }
      for (const int k : blob) hole_[static_cast<std::size_t>(k)] = 1;
    }
  }
  // Correlated axial noise: a white field over the box of hit pixels (plus the kernels'
  // reach), blurred row then column by normalized Gaussians. Each white value depends on
  // its pixel's key only, so the field is the same for any thread count. With a
  // low-frequency term, a second field (its own stream; on a grid with low_stride_px > 1)
  // is blurred by its kernels and the two are mixed by their shares of the variance, or,
  // without the angle term in the low field, kept apart and scaled per pixel.
  const AxialNoise& ax = noise.axial;
  const bool fine = ax.enabled && !rows_kernel_.empty();
  const bool low = ax.enabled && !low_rows_kernel_.empty();
  const bool correlated = fine || low;
  int bu0 = W, bu1 = -1, bv0 = H, bv1 = -1;
  if (correlated) {
    // Hits lie in `hits`; the scan also covers `noisy`, so that the field buffers, which are
    // not cleared, are written at every pixel the pass below reads, whatever a caller
    // passes. Min and max are exact in any order.
    PixelBox scan = hits;
    if (!noisy.empty())
      scan = hits.empty() ? noisy
                          : PixelBox{std::min(hits.u0, noisy.u0), std::max(hits.u1, noisy.u1),
                                     std::min(hits.v0, noisy.v0), std::max(hits.v1, noisy.v1)};
    const int v_lo = std::max(0, scan.v0), v_hi = std::min(H - 1, scan.v1);
    const int u_lo = std::max(0, scan.u0), u_hi = std::min(W - 1, scan.u1);
#pragma omp parallel for schedule(static) num_threads(threads) \
    reduction(min : bu0, bv0) reduction(max : bu1, bv1)
    for (int v = v_lo; v <= v_hi; ++v) {
      const float* row = in.depth_m.data() + static_cast<std::size_t>(v) * W;
      int first = u_hi + 1, last = u_lo - 1;
      for (int u = u_lo; u <= u_hi; ++u)
        if (row[u] > 0) {
          first = u;
          break;
        }
      if (first > u_hi) continue;
      for (int u = u_hi; u >= first; --u)
        if (row[u] > 0) {
          last = u;
          break;
        }
      bu0 = std::min(bu0, first), bu1 = std::max(bu1, last);
      bv0 = std::min(bv0, v), bv1 = std::max(bv1, v);
    }
  }
  // White noise over the nodes [x0, x1] x [y0, y1] of a lattice `stride` nodes wide, node
  // (x, y) drawn from `stream` with key index y * stride + x (so its value depends on the
  // node alone, not on the box), then blurred by `rows` and `cols` unless they are empty.
  // Leaves the result in white_, (x1 - x0 + 1) values a row.
  const auto draw_blurred = [&](int x0, int x1, int y0, int y1, int stride, std::uint64_t stream,
                                const std::vector<float>& rows, const std::vector<float>& cols) {
    const int w = x1 - x0 + 1, h = y1 - y0 + 1;
    // Every value is written below (and by the blurs): no zeroing first.
    white_.resize(static_cast<std::size_t>(w) * h);
#pragma omp parallel for schedule(static) num_threads(threads)
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x)
        white_[static_cast<std::size_t>(y - y0) * w + (x - x0)] = static_cast<float>(
            normal(pixel_key(frame_seed, static_cast<std::size_t>(y) * stride + x), stream));
    if (!rows.empty()) {
      blurred_.resize(static_cast<std::size_t>(w) * h);
      blur_rows(white_, blurred_, w, h, rows, threads);
      blur_columns(blurred_, white_, w, h, cols, threads);
    }
  };
  // The field buffers are read inside the box only (every valid pixel of `noisy`, clipped
  // to the image above, lies in it), so they are not cleared: the first field written into
  // a buffer overwrites it over a rectangle that covers the box (weight * value, what adding
  // it to zero gives, bit for bit but for the sign of a zero, which z0 + sigma * field
  // does not see), and later ones add to it.
  // The field of `stream` over the box, blurred by `rows` then `cols` (white where they are
  // empty), each pixel's value times `weight` written (`overwrite`) or added into `field`.
  const auto add_field = [&](const std::vector<float>& rows, const std::vector<float>& cols,
                             std::uint64_t stream, float weight, bool overwrite,
                             std::vector<float>& field) {
    const int Ru = static_cast<int>(rows.size() / 2), Rv = static_cast<int>(cols.size() / 2);
    const int fu0 = std::max(0, bu0 - Ru), fu1 = std::min(W - 1, bu1 + Ru);
    const int fv0 = std::max(0, bv0 - Rv), fv1 = std::min(H - 1, bv1 + Rv);
    const int fw = fu1 - fu0 + 1, fh = fv1 - fv0 + 1;
    draw_blurred(fu0, fu1, fv0, fv1, W, stream, rows, cols);
    // (weight 1, overwriting, is the field itself, bit for bit: the one-field model)
#pragma omp parallel for schedule(static) num_threads(threads)
    for (int y = 0; y < fh; ++y) {
      const float* src = white_.data() + static_cast<std::ptrdiff_t>(y) * fw;
      float* dst = field.data() + static_cast<std::ptrdiff_t>(y + fv0) * W + fu0;
      if (overwrite)
        for (int x = 0; x < fw; ++x) dst[x] = weight * src[x];
      else
        for (int x = 0; x < fw; ++x) dst[x] += weight * src[x];
    }
  };
  // The low field on a grid of stride S: node (gx, gy) sits at pixel (gx S, gy S), and
  // the grid covers the image and one node beyond, so every pixel has its four nodes. A
  // node's white value depends on its index in that whole grid only, so a render of a box
  // sees the whole frame's field inside it; the blur runs over the nodes the box needs
  // plus the kernels' reach, and each pixel of the box interpolates bilinearly.
  const auto add_grid_field = [&](const std::vector<float>& rows, const std::vector<float>& cols,
                                  int S, float weight, bool overwrite, std::vector<float>& field) {
    const int GW = (W - 1) / S + 2, GH = (H - 1) / S + 2;
    const int Ru = static_cast<int>(rows.size() / 2), Rv = static_cast<int>(cols.size() / 2);
    const int gx0 = std::max(0, bu0 / S - Ru), gx1 = std::min(GW - 1, bu1 / S + 1 + Ru);
    const int gy0 = std::max(0, bv0 / S - Rv), gy1 = std::min(GH - 1, bv1 / S + 1 + Rv);
    const int gw = gx1 - gx0 + 1;
    draw_blurred(gx0, gx1, gy0, gy1, GW, kAxialLowGrid, rows, cols);
    const float step = 1.0F / static_cast<float>(S);
    // Each grid row the box reads, interpolated along u once (every S pixel rows share it),
    // then each pixel row between two of them: the same float operations per pixel as
    // interpolating both rows at each pixel, in half the work and in loops that vectorize.
    const int bw = bu1 - bu0 + 1;
    const int r0 = bv0 / S - gy0, r1 = bv1 / S + 1 - gy0;  // within white_'s rows
    along_u_.resize(static_cast<std::size_t>(r1 - r0 + 1) * bw);
#pragma omp parallel for schedule(static) num_threads(threads)
    for (int r = r0; r <= r1; ++r) {
      const float* src = white_.data() + static_cast<std::ptrdiff_t>(r) * gw;
      float* dst = along_u_.data() + static_cast<std::ptrdiff_t>(r - r0) * bw;
      for (int u = bu0; u <= bu1; ++u) {
        const int g = u / S - gx0;
        const float fx = static_cast<float>(u % S) * step;
        dst[u - bu0] = (1 - fx) * src[g] + fx * src[g + 1];
      }
    }
#pragma omp parallel for schedule(static) num_threads(threads)
    for (int v = bv0; v <= bv1; ++v) {
      const float fy = static_cast<float>(v % S) * step;
      const float* top = along_u_.data() + static_cast<std::ptrdiff_t>(v / S - gy0 - r0) * bw;
      const float* bottom = top + bw;
      float* dst = field.data() + static_cast<std::ptrdiff_t>(v) * W + bu0;
      if (overwrite)
        for (int i = 0; i < bw; ++i) dst[i] = weight * ((1 - fy) * top[i] + fy * bottom[i]);
      else
        for (int i = 0; i < bw; ++i) dst[i] += weight * ((1 - fy) * top[i] + fy * bottom[i]);
    }
  };
  const auto add_low = [&](float weight, bool overwrite, std::vector<float>& field) {
    if (ax.low_stride_px > 1)
      add_grid_field(low_rows_kernel_, low_cols_kernel_, ax.low_stride_px, weight, overwrite, field);
    else
      add_field(low_rows_kernel_, low_cols_kernel_, kAxialLow, weight, overwrite, field);
  };
  // Without the angle term in the low field, the two fields stay apart (unit variance
  // each) and are scaled per pixel below.
  const bool split = low && !ax.low_angle_term;
  // The two fields' shares of a + c z^2 as scales, once (std::sqrt may set errno, so the
  // compiler would take it at every pixel).
  const double fine_share = 1 - ax.low_share, low_scale = std::sqrt(ax.low_share);
  if (correlated && bu1 >= 0) {
    field_.resize(n);
    add_field(rows_kernel_, cols_kernel_, kAxial,
              split ? 1.0F : static_cast<float>(std::sqrt(fine_share)), true, field_);
    if (split) {
      low_field_.resize(n);
      add_low(1.0F, true, low_field_);
    } else if (low) {
      add_low(static_cast<float>(low_scale), false, field_);
    }
  }
  const double cos_max = std::cos(noise.dropouts.max_incidence);
  const double z_min = camera_.z_min, z_max = camera_.z_max;
  const double unit = K.depth_scale;
#pragma omp parallel for schedule(dynamic, 4) num_threads(threads)
  for (int v = noisy.v0; v <= noisy.v1; ++v) {
    for (int u = noisy.u0; u <= noisy.u1; ++u) {
      const std::size_t pix = static_cast<std::size_t>(v) * W + u;
      const double z0 = in.depth_m[pix];
      if (!(z0 > 0)) continue;  // nothing hit (a NaN too: ANaNDepthIsNoHit)
      const std::uint64_t key = pixel_key(frame_seed, pix);
      if (noise.shadow.enabled && !in.lit[pix]) continue;
      if (noise.dropouts.enabled) {
        const double reflect = in.reflectance[pix];
        if (in.cos_camera[pix] < cos_max || in.cos_projector[pix] < cos_max)
          continue;
        if (reflect * in.cos_projector[pix] / (z0 * z0) < noise.dropouts.min_signal) continue;
        if (hole_[pix]) continue;
      }
      double z = z0;
      if (noise.edges.enabled) {
        const EdgeEffects& e = noise.edges;
        bool near_edge = false;  // a farther neighbour (or one that sees nothing)
        bool far_1 = false, far_2 = false;  // a nearer pixel 1 or 2 px away
        double z_far = 0;        // the farthest neighbour across a jump, for flying pixels
        auto clean = [&](int uu, int vv) {
          return in.depth_m[static_cast<std::size_t>(vv) * W + uu];
        };
        const int du[4] = {-1, 1, 0, 0}, dv[4] = {0, 0, -1, 1};
        for (int k = 0; k < 4; ++k) {
          const int uu = u + du[k], vv = v + dv[k];
          if (uu < 0 || uu >= W || vv < 0 || vv >= H) continue;
          const double zn = clean(uu, vv);
          if (!(zn > 0) || zn - z0 > e.jump) {  // a NaN neighbour sees nothing too
            near_edge = true;
            z_far = std::max(z_far, zn);
          } else if (z0 - zn > e.jump) {
            far_1 = true;
          }
          // 2 px away: the jump must fall between the neighbour (on this pixel's surface)
          // and the pixel after it, not be the sum of two steps of a steep slope. Only
          // looked at when that band can drop anything (it costs a third of the pass).
          if (!(e.band_p2 > 0)) continue;
          const int u2 = u + kEdgeReachPx * du[k], v2 = v + kEdgeReachPx * dv[k];
          if (u2 < 0 || u2 >= W || v2 < 0 || v2 >= H) continue;
          const double z2 = clean(u2, v2);
          if (zn > 0 && std::abs(zn - z0) <= e.jump && z2 > 0 && zn - z2 > e.jump) far_2 = true;
        }
        // The far side first: its band is the camera's, whatever the near side does.
        if (far_1) {
          if (uniform(key, kEdge) < e.band_p1) continue;
        } else if (far_2) {
          if (uniform(key, kEdge) < e.band_p2) continue;
        } else if (near_edge) {
          if (uniform(key, kEdge) < e.p_drop) continue;
          if (z_far > 0 && uniform(key, kFlying) < e.p_flying) {
            const double lo = std::max(0.0, e.flying_position - e.flying_spread);
            const double hi = std::min(1.0, e.flying_position + e.flying_spread);
            z = z0 + (lo + uniform(key, kMix) * (hi - lo)) * (z_far - z0);  // between the two
          }
        }
      }
      if (split) {
        AxialNoise::Point p;
        if (angle_power_.empty()) {
          p = ax.point(z0, in.incidence[pix]);
        } else {  // as AxialNoise::point, q^power from the table (a NaN incidence reads NaN)
          p.z = z0;
          p.root_z = std::sqrt(std::max(z0, 1e-6));
          p.q_power = angle_power_(std::abs(static_cast<double>(in.incidence[pix])));
        }
        const double base = ax.base(p), angle = ax.sigma(p) - base;
        double pixel_base = base;
        if (!pixel_factor_.empty()) pixel_base *= pixel_factor_(z0);
        z += std::sqrt(fine_share * pixel_base * pixel_base + angle * angle) * static_cast<double>(field_[pix]) +
             low_scale * base * static_cast<double>(low_field_[pix]);
      } else if (noise.axial.enabled) {
        z += noise.axial.sigma(z0, in.incidence[pix]) *
             (correlated ? static_cast<double>(field_[pix]) : normal(key, kAxial));
      }
      // Written so that a NaN (from a NaN incidence, say) fails it: the cast below is
      // undefined for one.
      if (!(z >= z_min && z <= z_max)) continue;
      const long q = static_cast<long>(z / unit + 0.5);  // z > 0 here
      if (q <= 0 || q > 65535) continue;
      depth.data[pix] = static_cast<std::uint16_t>(q);
      depth_m[pix] = static_cast<float>(noise.quantize ? q * unit : z);
    }
  }
  if (noise.edges.enabled && noise.edges.drop_steps) {
    // What the pass above reported, read whole before anything is dropped, so a pixel's fate
    // does not depend on the order (or the thread) in which its neighbours are visited. The
    // reported depths are the PNG's units: the camera's own rule sees nothing finer.
    steps_ = depth.data;
    // The camera's rule, (a - b) unit > jump for a valid neighbour b, as a threshold on the
    // integer difference (step_units_, set up in the constructor). A neighbour outside the
    // image is a pixel that reports nothing (0), which never drops anything: the rows above
    // the first and below the last read none_, a row of zeros.
    const int d_min = step_units_;
    // A pixel drops when its nearest valid neighbour b has a - b >= d_min. b - 1 in 16 bits
    // sends "nothing" (0) to 65535, above every valid b - 1, so the least of the four is the
    // nearest valid neighbour's, less 1 (65535 when none is valid, which never drops).
    const auto less_one = [](int b) { return static_cast<std::uint16_t>(b - 1); };
#pragma omp parallel for schedule(static) num_threads(threads)
    for (int v = noisy.v0; v <= noisy.v1; ++v) {
      const std::uint16_t* row = steps_.data() + static_cast<std::ptrdiff_t>(v) * W;
      const std::uint16_t* up = v > 0 ? row - W : none_.data();
      const std::uint16_t* down = v < H - 1 ? row + W : none_.data();
      std::uint16_t* out = depth.data.data() + static_cast<std::ptrdiff_t>(v) * W;
      float* out_m = depth_m.data() + static_cast<std::ptrdiff_t>(v) * W;
      // Both outputs written whatever the outcome, as their bits and a mask of all ones
      // (kept) or zeros (dropped: 0 and +0.0), so that the loop vectorizes: a select that
      // keeps the old value is a store only where it drops, which the compiler may not
      // turn into a store everywhere (another thread could own the pixels it skips).
      const auto check = [&](int u, int left, int right) {
        const int a = row[u];
        const int m = std::min(std::min(less_one(left), less_one(right)),
                               std::min(less_one(up[u]), less_one(down[u])));
        const std::uint32_t keep = a - 1 - m >= d_min ? 0U : ~0U;
        out[u] = static_cast<std::uint16_t>(out[u] & keep);
        out_m[u] = std::bit_cast<float>(std::bit_cast<std::uint32_t>(out_m[u]) & keep);
      };
      // The two border columns apart, so that the loop between them has no bounds to test.
      const int u_lo = std::max(noisy.u0, 1), u_hi = std::min(noisy.u1, W - 2);
      if (noisy.u0 == 0) check(0, 0, W > 1 ? row[1] : 0);
      for (int u = u_lo; u <= u_hi; ++u) check(u, row[u - 1], row[u + 1]);
      if (noisy.u1 == W - 1 && W > 1) check(W - 1, row[W - 2], 0);
    }
  }
}

}  // namespace linksight::sim
