// The sensor's stages on their own (sim/sensor/src/sensor_{cull,noise}.cpp): the culling
// bounds hold every ray they must, and the noise model runs on hand-made noise-free
// images without Embree and reproduces what Sensor::render gave.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>

#include "linksight/sim/lerp_table.hpp"
#include "linksight/sim/sensor.hpp"
#include "linksight/sim/sensor_cull.hpp"
#include "linksight/sim/sensor_noise.hpp"
#include "test_support.hpp"

namespace linksight::sim {
namespace {

constexpr double kStageSigmaRelTol = 0.10;  // as the Sensor's plane test: sigma within 10%

// Noise-free images of a plane facing the camera at depth `z` [m], every pixel hit.
struct Plate {
  int width = 0, height = 0;
  std::vector<float> depth_m, incidence, cos_camera, cos_projector, reflectance;
  std::vector<std::uint8_t> lit;
  // `theta`: the incidence every pixel reports [rad] (the noise reads it, not the geometry).
  Plate(const io::Intrinsics& K, double z, double theta = 0) : width(K.width), height(K.height) {
    const std::size_t n = static_cast<std::size_t>(width) * height;
    depth_m.assign(n, static_cast<float>(z));
    incidence.assign(n, static_cast<float>(theta));
    cos_camera.assign(n, 1.0F);
    cos_projector.assign(n, 1.0F);
    reflectance.assign(n, 1.0F);
    lit.assign(n, 1);
  }
  [[nodiscard]] NoiseInput input() const {
    return {width, height, depth_m, incidence, cos_camera, cos_projector, reflectance, lit};
  }
};

// The axial field of `n` (the other terms off) on a plate at `z` (0.6 m) over 4 frames, every
// pixel at incidence `theta` [rad]: its sigma [m] and its correlation at lags 0..lags
// along rows and along columns, over pixels at least `border` from the image's edge (the
// filters' reach); the first frame's depth (with `threads`).
struct PlateField {
  double sigma = 0;
  std::vector<double> rows, cols;
  std::vector<float> first;
};
// Only the axial noise, sigma = a_m + k_theta q^p / sqrt(z) (c = 0; k_theta 0 unless set).
NoiseParams axial_only(double a_m) {
  NoiseParams n = NoiseParams::off();
  n.axial.enabled = true;
  n.axial.a = a_m;
  n.axial.c = 0;
  n.axial.k_theta = 0;
  return n;
}

PlateField plate_field(const NoiseParams& n, int lags, int border, double theta = 0, int threads = 2,
                       double z = 0.6) {
  const CameraParams camera;
  const Plate plate(camera.intrinsics, z, theta);
  SensorNoise noise(n, camera);
  std::vector<double> rows(static_cast<std::size_t>(lags) + 1), cols(rows.size());
  double count = 0;
  PlateField out;
  for (std::uint64_t frame = 0; frame < 4; ++frame) {
    io::DepthImage depth;
    std::vector<float> depth_m;
    noise.apply(plate.input(), 9, frame, threads, depth, depth_m);
    if (frame == 0) out.first = depth_m;
    const int W = plate.width;
    const auto e = [&](int u, int v) {
      return static_cast<double>(depth_m[static_cast<std::size_t>(v) * W + u]) - z;
    };
    for (int v = border; v < plate.height - border - lags; ++v)
      for (int u = border; u < W - border - lags; ++u) {
        for (int l = 0; l <= lags; ++l) {
          rows[static_cast<std::size_t>(l)] += e(u, v) * e(u + l, v);
          cols[static_cast<std::size_t>(l)] += e(u, v) * e(u, v + l);
        }
        ++count;
      }
  }
  out.sigma = std::sqrt(rows[0] / count);
  for (std::size_t l = 0; l < rows.size(); ++l) {
    out.rows.push_back(rows[l] / rows[0]);
    out.cols.push_back(cols[l] / cols[0]);
  }
  return out;
}

// The depth [m] of a plate at 0.6 m through `n`, frame `frame` of seed `seed`.
std::vector<float> plate_depth(const NoiseParams& n, std::uint64_t seed, std::uint64_t frame,
                               int threads) {
  const CameraParams camera;
  const Plate plate(camera.intrinsics, 0.6);
  SensorNoise noise(n, camera);
  io::DepthImage depth;
  std::vector<float> depth_m;
  noise.apply(plate.input(), seed, frame, threads, depth, depth_m);
  return depth_m;
}

TEST(SensorNoise, ReproducesTheRenderFromItsNoiseFreeImages) {
  // Every term on (holes, edges, shadows, correlated noise), the link in front of a wall.
  SensorParams p;
  p.camera.X_WC = look_at({0.25, -0.5, 0.5}, {0.25, 0.0, 0.5});
  p.noise = NoiseParams::sr300();
  p.noise.dropouts.hole_rate = 20;
  p.threads = 2;
  const ComponentGeometry g;
  BackgroundObject wall;
  wall.shape.half_extents = Eigen::Vector3d(3.0, 0.01, 3.0);
  wall.X_WO.translation() = Eigen::Vector3d(0.25, 0.3, 0.5);
  Sensor sensor(p, g, {}, {wall});
  const DepthFrame frame = sensor.render(test::straight_chain_frames(g), 0.0, 42, 7);
  std::size_t hits = 0;
  for (const std::uint16_t d : frame.depth.data) hits += d != 0;
  ASSERT_GT(hits, 100000U);

  SensorNoise noise(p.noise, p.camera);
  io::DepthImage depth;
  std::vector<float> depth_m;
  noise.apply(sensor.last_noise_input(frame), 42, 7, 1, depth, depth_m);
  EXPECT_EQ(depth.data, frame.depth.data);
  EXPECT_EQ(depth_m, frame.depth_m);
  // Another frame draws other noise.
  noise.apply(sensor.last_noise_input(frame), 42, 8, 1, depth, depth_m);
  EXPECT_NE(depth.data, frame.depth.data);
}

TEST(SensorNoise, PlaneSigmaMatchesTheModelWithoutEmbree) {
  NoiseParams n = NoiseParams::off();
  n.axial.enabled = true;
  n.axial.correlation_px = 0;
  const CameraParams camera;
  for (const double z : {0.4, 0.9}) {
    const Plate plate(camera.intrinsics, z);
    SensorNoise noise(n, camera);
    io::DepthImage depth;
    std::vector<float> depth_m;
    noise.apply(plate.input(), 3, 1, 2, depth, depth_m);
    double sum = 0, sum2 = 0;
    for (const float d : depth_m) {
      ASSERT_GT(d, 0.0F);
      sum += d - z;
      sum2 += (d - z) * (d - z);
    }
    const double N = static_cast<double>(depth_m.size());
    const double sigma = std::sqrt(sum2 / N - (sum / N) * (sum / N));
    const double model = n.axial.sigma(z, 0.0);
    EXPECT_NEAR(sigma / model, 1.0, kStageSigmaRelTol) << "z = " << z;
    EXPECT_NEAR(sum / N, 0.0, 0.05 * model) << "z = " << z << ": biased";
  }
}

TEST(SensorNoise, ShadowRangeAndRegionRulesGiveNoDepth) {
  NoiseParams n = NoiseParams::off();
  n.shadow.enabled = true;
  n.quantize = true;
  const CameraParams camera;
  Plate plate(camera.intrinsics, 0.5);
  plate.lit[10] = 0;                                       // in the projector's shadow
  plate.depth_m[11] = static_cast<float>(camera.z_max + 0.1);  // beyond the range
  plate.depth_m[12] = 0.0F;                                // nothing hit
  SensorNoise noise(n, camera);
  io::DepthImage depth;
  std::vector<float> depth_m;
  const PixelBox noisy{0, 99, 0, 0};  // the first 100 pixels of row 0
  noise.apply(plate.input(), 1, 1, noisy, {0, plate.width - 1, 0, plate.height - 1}, 1, depth, depth_m);
  ASSERT_EQ(depth.data.size(), plate.depth_m.size());
  for (int i = 0; i < 100; ++i) {
    const bool none = i == 10 || i == 11 || i == 12;
    EXPECT_EQ(depth.data[i] == 0, none) << "pixel " << i;
  }
  // Quantized to the depth unit; nothing outside `noisy`.
  const double unit = camera.intrinsics.depth_scale;
  EXPECT_EQ(depth.data[0], static_cast<std::uint16_t>(std::lround(0.5 / unit)));
  EXPECT_FLOAT_EQ(depth_m[0], static_cast<float>(depth.data[0] * unit));
  EXPECT_EQ(depth.data[100], 0);
  EXPECT_EQ(depth.data[static_cast<std::size_t>(plate.width)], 0);
}

TEST(SensorNoise, ANaNDepthIsNoHit) {
  // A cast never gives one; an input that does must read as nothing hit, exactly as a 0
  // (its neighbours' edge rules included), and a NaN incidence must not reach the cast to
  // the depth unit (undefined: the sanitizer stage's float-cast-overflow sees it, a plain
  // build may not). Every term on, edge bands sure to fire.
  const CameraParams camera;
  NoiseParams n = NoiseParams::sr300();
  n.edges.p_drop = 1;
  const int W = camera.intrinsics.width, H = camera.intrinsics.height;
  const std::size_t c = static_cast<std::size_t>(H / 2) * W + W / 2;  // the image's centre
  const auto image = [&](float centre_depth, float centre_incidence) {
    Plate plate(camera.intrinsics, 0.6);
    plate.depth_m[c] = centre_depth;
    plate.incidence[c] = centre_incidence;
    SensorNoise noise(n, camera);
    std::pair<io::DepthImage, std::vector<float>> out;
    noise.apply(plate.input(), 3, 0, 1, out.first, out.second);
    return out;
  };
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const auto zero = image(0.0F, 0.0F);
  const auto nan_depth = image(nan, 0.0F);
  EXPECT_EQ(nan_depth.first.data, zero.first.data);
  EXPECT_EQ(nan_depth.second, zero.second);
  // The 0's neighbours are edge pixels, dropped with p_drop 1: the rule did fire.
  EXPECT_EQ(zero.first.data[c + 1], 0);
  EXPECT_GT(zero.first.data[c + 3], 0);
  const auto nan_incidence = image(0.6F, nan);
  EXPECT_EQ(nan_incidence.first.data[c], 0);
  std::size_t not_finite = 0;
  for (const float z : nan_incidence.second) not_finite += !std::isfinite(z);
  EXPECT_EQ(not_finite, 0U);
}

TEST(SensorNoise, SameDepthForAnyThreadCount) {
  const CameraParams camera;
  const Plate plate(camera.intrinsics, 0.6);
  NoiseParams n = NoiseParams::sr300();
  n.dropouts.hole_rate = 10;
  SensorNoise noise(n, camera);
  io::DepthImage one, three;
  std::vector<float> one_m, three_m;
  noise.apply(plate.input(), 5, 2, 1, one, one_m);
  noise.apply(plate.input(), 5, 2, 3, three, three_m);
  EXPECT_EQ(one.data, three.data);
  EXPECT_EQ(one_m, three_m);
}

// The field buffers are not cleared between frames (sensor_noise.cpp): the pixels of
// `noisy` get the whole frame's values whatever box `hits` names (here a corner of the
// plate only, after a frame of other draws has filled the buffers), for both presets, and
// a `noisy` box beyond the image is cut to it.
TEST(SensorNoise, NoisyBoxGetsTheWholeFramesValuesWhateverTheHitsBox) {
  const CameraParams camera;
  const Plate plate(camera.intrinsics, 0.6);
  const int W = plate.width, H = plate.height;
  const PixelBox noisy{100, 400, 80, 300}, corner{0, 50, 0, 40};
  for (const NoiseParams& n : {NoiseParams::sr300(), NoiseParams::sr300_one_field()}) {
    SensorNoise noise(n, camera);
    io::DepthImage whole, part;
    std::vector<float> whole_m, part_m;
    noise.apply(plate.input(), 5, 2, 2, whole, whole_m);
    noise.apply(plate.input(), 6, 3, 2, part, part_m);  // other draws in the buffers
    noise.apply(plate.input(), 5, 2, noisy, corner, 2, part, part_m);
    int compared = 0;
    for (int v = 0; v < H; ++v)
      for (int u = 0; u < W; ++u) {
        const std::size_t i = static_cast<std::size_t>(v) * W + u;
        if (!noisy.contains(u, v)) {
          ASSERT_EQ(part.data[i], 0) << u << ", " << v << ": outside the noisy box";
          continue;
        }
        ASSERT_EQ(part.data[i], whole.data[i]) << u << ", " << v;
        ASSERT_EQ(part_m[i], whole_m[i]) << u << ", " << v;
        compared += whole.data[i] != 0;
      }
    EXPECT_GT(compared, 50000);
    // A box reaching beyond the image is cut to it: the whole frame.
    noise.apply(plate.input(), 5, 2, PixelBox{-5, W + 5, -5, H + 5}, corner, 2, part, part_m);
    EXPECT_EQ(part.data, whole.data);
    EXPECT_EQ(part_m, whole_m);
  }
}

// The two-term axial field of the tests below: sigma a, the pixel-scale term with widths
// 1 px along rows and 2 px along columns, the low-frequency term with `low_rows` and
// `low_cols` [px] and kTwoTermShare of the variance, drawn every `stride` px.
constexpr double kTwoTermSigma = 0.002, kTwoTermShare = 0.6;  // [m], of the variance
NoiseParams two_term_noise(double low_rows, double low_cols, int stride = 1) {
  NoiseParams n = axial_only(kTwoTermSigma);
  n.axial.correlation_px = 1.0;
  n.axial.correlation_cols_px = 2.0;
  n.axial.low_share = kTwoTermShare;
  n.axial.low_rows_px = low_rows;
  n.axial.low_cols_px = low_cols;
  n.axial.low_stride_px = stride;
  return n;
}
// On a fronto-parallel plate, without other noise: sigma within kStageSigmaRelTol of a, and
// the correlation at lag L along each direction (1 - s) exp(-L^2 / 4 w^2) + s exp(-L^2 /
// 4 W^2) with that direction's widths w, W, within 0.03 (seen: 0.01 at every lag).
PlateField expect_two_term_field(const NoiseParams& n) {
  constexpr double kRhoTol = 0.03;
  constexpr int kLags = 6, kBorder = 24;  // away from the image border by the reach, 3 x 8 px
  const PlateField f = plate_field(n, kLags, kBorder);
  EXPECT_NEAR(f.sigma, kTwoTermSigma, kStageSigmaRelTol * kTwoTermSigma);
  const auto model = [&](int l, double w, double big) {
    return (1 - kTwoTermShare) * std::exp(-l * l / (4 * w * w)) +
           kTwoTermShare * std::exp(-l * l / (4 * big * big));
  };
  for (int l = 1; l <= kLags; ++l) {
    EXPECT_NEAR(f.rows[l], model(l, 1.0, n.axial.low_rows_px), kRhoTol) << "along rows, lag " << l;
    EXPECT_NEAR(f.cols[l], model(l, 2.0, n.axial.low_cols_px), kRhoTol) << "along columns, lag " << l;
  }
  return f;
}

// The two-term axial field (issue 20), its low term 4 x 8 px.
TEST(SensorNoise, TwoTermFieldHasItsSigmaAndEachDirectionsCorrelation) {
  const PlateField f = expect_two_term_field(two_term_noise(4.0, 8.0));
  // The directions differ by far more than the tolerance: 0.56 against 0.81 at lag 3.
  EXPECT_GT(f.cols[3] - f.rows[3], 0.15);
}

// The low-frequency field drawn on a grid of 2 px and interpolated (low_stride_px): sigma
// and each direction's correlation as on every pixel (within the same tolerances), the
// same for any thread count, and not the every-pixel field's draws; widths under the
// stride are refused.
TEST(SensorNoise, LowFieldOnAGridKeepsItsSigmaAndCorrelation) {
  NoiseParams n = two_term_noise(6.0, 8.0, 2);
  const PlateField f = expect_two_term_field(n);
  constexpr int kBorder = 24;
  EXPECT_EQ(plate_field(n, 0, kBorder, 0, 1).first, f.first);
  EXPECT_EQ(plate_field(n, 0, kBorder, 0, 3).first, f.first);
  const NoiseParams every = two_term_noise(6.0, 8.0, 1);
  EXPECT_NE(plate_field(every, 0, kBorder).first, f.first);
  n.axial.low_rows_px = 3.5;
  const std::string e =
      test::error_of<std::invalid_argument>([&] { (void)SensorNoise(n, CameraParams{}); });
  EXPECT_NE(e.find("noise.axial.low_rows_px = 3.5"), std::string::npos) << e;
  EXPECT_NE(e.find("must be >= 2 x low_stride_px (2)"), std::string::npos) << e;
  n.axial.low_rows_px = 4;
  EXPECT_NO_THROW((void)SensorNoise(n, CameraParams{}));
}

// The low-frequency field without the angle term (`low_angle_term: false`, issue 20): at
// normal incidence it is the two-term field above; at 60 degrees, where the angle term t
// equals the base a, the pixel-scale field carries sqrt((1 - s) a^2 + t^2) and the low one
// sqrt(s) a, so sigma is sqrt(a^2 + t^2) and the lag-L correlation
// ((1 - s) a^2 + t^2) rho_pixel(L) + s a^2 rho_low(L), over sigma^2. With the term (the
// default) sigma is a + t and the shares are those at normal incidence. The same for any
// thread count, and with the low field on a 2 px grid.
TEST(SensorNoise, LowFieldWithoutTheAngleTermLeavesItToThePixelScaleField) {
  constexpr double kSigma = 0.002;  // a [m]
  constexpr double kShare = 0.8, kPixelPx = 1.0, kLowPx = 6.0;
  constexpr double kRhoTol = 0.04;  // as the Matern test's: 4 frames of a smooth field
  const double theta = std::numbers::pi / 3;
  NoiseParams n = axial_only(kSigma);
  // t = k q^2 / sqrt(z) with q = theta / (pi/2 - theta) = 2 at 60 degrees, z = 0.6 m: t = a.
  n.axial.k_theta = kSigma * std::sqrt(0.6) / 4;
  n.axial.correlation_px = kPixelPx;
  n.axial.low_share = kShare;
  n.axial.low_rows_px = kLowPx;
  n.axial.low_cols_px = kLowPx;
  ASSERT_NEAR(n.axial.sigma(0.6, theta), 2 * kSigma, 1e-12);
  const auto rho = [](int l, double w) { return std::exp(-l * l / (4 * w * w)); };
  constexpr int kLags = 4, kBorder = 20;  // the low field's reach, 3 x 6 px
  for (const auto& [with_angle, stride] : {std::pair{true, 1}, std::pair{false, 1}, std::pair{false, 2}}) {
    n.axial.low_angle_term = with_angle;
    n.axial.low_stride_px = stride;
    SCOPED_TRACE(std::string(with_angle ? "low_angle_term true" : "low_angle_term false") +
                 ", low_stride_px " + std::to_string(stride));
    const PlateField flat = plate_field(n, kLags, kBorder);
    EXPECT_NEAR(flat.sigma, kSigma, kStageSigmaRelTol * kSigma);
    const PlateField steep = plate_field(n, kLags, kBorder, theta, 1);
    const double pixel = with_angle ? 1 - kShare : (1 - kShare + 1) / 2;  // of sigma^2
    const double sigma = with_angle ? 2 * kSigma : std::sqrt(2.0) * kSigma;
    EXPECT_NEAR(steep.sigma, sigma, kStageSigmaRelTol * sigma);
    for (int l = 1; l <= kLags; ++l) {
      const double model = pixel * rho(l, kPixelPx) + (1 - pixel) * rho(l, kLowPx);
      EXPECT_NEAR(flat.rows[l], (1 - kShare) * rho(l, kPixelPx) + kShare * rho(l, kLowPx), kRhoTol)
          << "normal incidence, lag " << l;
      EXPECT_NEAR(steep.rows[l], model, kRhoTol) << "60 degrees, along rows, lag " << l;
      EXPECT_NEAR(steep.cols[l], model, kRhoTol) << "60 degrees, along columns, lag " << l;
    }
    // The same image for 1 thread (steep) and 3.
    EXPECT_EQ(plate_field(n, 0, kBorder, theta, 3).first, steep.first);
  }
}

// The angle term's power (issue 20): at 60 degrees q = theta / (pi/2 - theta) = 2, so with
// k_theta / sqrt(z) = a / 2 the term is a q^p / 2: a for the power 1, 2a for Nguyen et
// al.'s 2, and the plate's one-field noise reads a + t. The power 2 is q * q to the bit,
// so that the scenes from before the power draw the same images.
TEST(SensorNoise, AnglePowerSetsHowFastTheAngleTermGrows) {
  constexpr double kSigma = 0.002;  // a [m]
  const double theta = std::numbers::pi / 3;
  NoiseParams n = axial_only(kSigma);
  n.axial.k_theta = kSigma * std::sqrt(0.6) / 2;
  // The power 2 as the formula was written before the power existed, to the bit.
  const AxialNoise& ax = n.axial;
  for (const double z : {0.31, 0.6, 0.97})
    for (const double th : {0.0, 0.2, 0.7, 1.1, 1.3, 1.5}) {
      const double capped = std::min(th, ax.theta_cap);
      const double q = capped / (std::numbers::pi / 2 - capped);
      EXPECT_EQ(ax.sigma(z, th), ax.a + ax.c * z * z + ax.k_theta / std::sqrt(z) * q * q)
          << "z " << z << ", theta " << th;
    }
  for (const double power : {1.0, 2.0}) {
    n.axial.angle_power = power;
    SCOPED_TRACE("angle_power " + std::to_string(power));
    const double sigma = kSigma * (1 + power);
    ASSERT_NEAR(n.axial.sigma(0.6, theta), sigma, 1e-12);
    EXPECT_NEAR(plate_field(n, 0, 0).sigma, kSigma, kStageSigmaRelTol * kSigma);
    EXPECT_NEAR(plate_field(n, 0, 0, theta).sigma, sigma, kStageSigmaRelTol * sigma);
  }
  // With the two fields apart the angle term t goes into the pixel-scale field in
  // quadrature, sigma = sqrt(a^2 + t^2), and the sensor reads q^power from a table (but
  // for the power 2): t = a 2^(p - 1).
  n.axial.low_share = 0.5;
  n.axial.low_angle_term = false;
  constexpr int kBorder = 20;  // the low field's reach, 3 x 6 px
  for (const double power : {1.625, 2.0}) {
    n.axial.angle_power = power;
    SCOPED_TRACE("two fields, angle_power " + std::to_string(power));
    const double t = kSigma * std::pow(2.0, power - 1);
    const double sigma = std::hypot(kSigma, t);
    EXPECT_NEAR(plate_field(n, 0, kBorder, theta).sigma, sigma, kStageSigmaRelTol * sigma);
  }
}

// The sensor's tables (the depth factor, the angle power): linear between steps, so off
// the steps within the curvature's bound of the function; at the ends the end's value,
// beyond them held; NaN reads NaN (before any cast to an index); a range or step it cannot
// hold refused. q^1.625 over [0, 80 deg] in the sensor's steps, as the sensor makes it, is
// within 1e-4 of std::pow (relative) from 1 to 75 degrees (docs/sensor.md).
TEST(LerpTable, InterpolatesHoldsItsEndsAndRefusesWhatItCannotHold) {
  const LerpTable square(0, 2, 4, [](double x) { return x * x; });
  EXPECT_EQ(square(0.5), 0.25);  // on a step
  EXPECT_EQ(square(0.75), 0.625);  // halfway between 0.25 and 1
  EXPECT_EQ(square(2.0), 4.0);
  EXPECT_EQ(square(3.0), 4.0);
  EXPECT_EQ(square(-1.0), 0.0);
  EXPECT_TRUE(std::isnan(square(std::numeric_limits<double>::quiet_NaN())));
  EXPECT_TRUE(LerpTable().empty());
  EXPECT_FALSE(square.empty());
  for (const auto& [lo, hi, steps] :
       {std::tuple{1.0, 1.0, std::size_t{4}}, std::tuple{0.0, 1.0, std::size_t{0}},
        std::tuple{0.0, 1e-310, std::size_t{4096}}})
    EXPECT_THROW(LerpTable(lo, hi, steps, [](double x) { return x; }), std::invalid_argument)
        << lo << " to " << hi << " in " << steps;
  AxialNoise ax;
  ax.angle_power = 1.625;
  const LerpTable power(0, ax.theta_cap, SensorNoise::kAngleTableSteps,
                        [&](double th) { return ax.point(0, th).q_power; });
  constexpr double kTableRelTol = 1e-4;
  for (double deg = 1; deg <= 75; deg += 0.37) {  // off the steps (80 deg / kAngleTableSteps apart)
    const double th = deg * std::numbers::pi / 180;
    const double exact = std::pow(th / (std::numbers::pi / 2 - th), 1.625);
    EXPECT_NEAR(power(th), exact, kTableRelTol * exact) << deg << " deg";
  }
  EXPECT_NEAR(power(1.5), ax.point(0, ax.theta_cap).q_power, 1e-12) << "held at the cap";
}

// The pixel-scale field's depth power (issue 20), on the two-term field above without the
// angle term: on a plate at depth z the pixel-scale field carries (1 - s) (a r^p)^2 of the
// variance, r = z' / ref with z' held to the range, and the low field s a^2, so sigma^2 =
// ((1 - s) r^(2p) + s) a^2 and the lag-L correlation mixes the two fields' by those shares.
// At the reference depth nothing changes; beyond the range, either side, the factor is the
// one at its end, not the power law's.
TEST(SensorNoise, PixelDepthPowerScalesThePixelScaleFieldOnly) {
  constexpr double kLowPx = 6.0, kPower = 2.0, kRef = 0.6;
  constexpr double kRhoTol = 0.04;  // as the test above
  NoiseParams n = two_term_noise(kLowPx, kLowPx);  // pixel-scale widths 1 x 2 px
  n.axial.low_angle_term = false;
  n.axial.pixel_depth_power = kPower;
  n.axial.pixel_depth_ref_m = kRef;
  n.axial.pixel_depth_min_m = 0.3;
  n.axial.pixel_depth_max_m = 0.8;
  const auto rho = [](int l, double w) { return std::exp(-l * l / (4 * w * w)); };
  constexpr int kLags = 4, kBorder = 20;
  // z, and the depth the factor is read at: 1.0 m is past the range's end, 0.8 m, and
  // 0.25 m before its start, 0.3 m.
  for (const auto& [z, held] : {std::pair{0.6, 0.6}, std::pair{0.75, 0.75}, std::pair{1.0, 0.8},
                                std::pair{0.25, 0.3}}) {
    SCOPED_TRACE("z " + std::to_string(z));
    const double r2p = std::pow(held / kRef, 2 * kPower);
    const double pixel = (1 - kTwoTermShare) * r2p, total = pixel + kTwoTermShare;  // of a^2
    const double sigma = std::sqrt(total) * kTwoTermSigma;
    const PlateField f = plate_field(n, kLags, kBorder, 0, 2, z);
    EXPECT_NEAR(f.sigma, sigma, kStageSigmaRelTol * sigma);
    for (int l = 1; l <= kLags; ++l) {
      const double low = kTwoTermShare * rho(l, kLowPx);
      EXPECT_NEAR(f.rows[l], (pixel * rho(l, 1.0) + low) / total, kRhoTol) << "lag " << l;
      EXPECT_NEAR(f.cols[l], (pixel * rho(l, 2.0) + low) / total, kRhoTol) << "lag " << l;
    }
  }
  // The unheld power law would read 1.92 a at 1.0 m, where the held factor gives 1.37 a:
  // more than the tolerance apart, so the check above tells them apart.
  ASSERT_GT(std::sqrt((1 - kTwoTermShare) * std::pow(1.0 / kRef, 2 * kPower) + kTwoTermShare) -
                std::sqrt((1 - kTwoTermShare) * std::pow(0.8 / kRef, 2 * kPower) + kTwoTermShare),
            2 * kStageSigmaRelTol * 1.4);
  // The same draws with and without the power, the low field nearly off: each pixel's
  // offset is scaled by the factor itself, r^p (1.56 at 0.75 m; its square would be 2.44).
  NoiseParams pixel_only = n;
  pixel_only.axial.low_share = 0.001;
  NoiseParams no_power = pixel_only;
  no_power.axial.pixel_depth_power = 0;
  constexpr double kZ = 0.75;
  const std::vector<float> with = plate_field(pixel_only, 0, kBorder, 0, 2, kZ).first;
  const std::vector<float> without = plate_field(no_power, 0, kBorder, 0, 2, kZ).first;
  double xy = 0, xx = 0;
  for (std::size_t i = 0; i < with.size(); ++i) {
    xy += (with[i] - kZ) * (without[i] - kZ);
    xx += (without[i] - kZ) * (without[i] - kZ);
  }
  EXPECT_NEAR(xy / xx, std::pow(kZ / kRef, kPower), 0.01);  // the low field's 0.1% off
  // Without the two fields apart the power does nothing, as the low field's widths without
  // a low field; the range must be one, and start past 0 for a negative power.
  NoiseParams joint = n;
  joint.axial.low_angle_term = true;
  NoiseParams joint_no_power = joint;
  joint_no_power.axial.pixel_depth_power = 0;
  EXPECT_EQ(plate_field(joint, 0, kBorder, 0, 2, kZ).first,
            plate_field(joint_no_power, 0, kBorder, 0, 2, kZ).first);
  NoiseParams bad = n;
  bad.axial.pixel_depth_max_m = 0.3;
  const std::string e =
      test::error_of<std::invalid_argument>([&] { (void)SensorNoise(bad, CameraParams{}); });
  EXPECT_NE(e.find("noise.axial.pixel_depth_max_m = 0.3: must be > pixel_depth_min_m (0.3)"),
            std::string::npos) << e;
  bad = n;
  bad.axial.pixel_depth_power = -1;
  bad.axial.pixel_depth_min_m = 0;
  const std::string e0 =
      test::error_of<std::invalid_argument>([&] { (void)SensorNoise(bad, CameraParams{}); });
  EXPECT_NE(e0.find("noise.axial.pixel_depth_min_m = 0: must be > 0 with a negative pixel_depth_power (-1)"),
            std::string::npos) << e0;
}

// The new settings at their defaults are the one-field model, bit for bit (old scenes keep
// their images); an isotropic width given twice is the same field; the two-term field is
// the same for any thread count and differs from the one-field one.
TEST(SensorNoise, TwoTermFieldOffIsTheOneFieldModel) {
  const CameraParams camera;
  const auto render = [&](const NoiseParams& n, int threads) { return plate_depth(n, 5, 2, threads); };
  const NoiseParams one = NoiseParams::sr300_one_field();
  ASSERT_EQ(one.axial.low_share, 0.0);
  ASSERT_EQ(one.axial.correlation_cols_px, 0.0);
  NoiseParams twice = one;
  twice.axial.correlation_cols_px = one.axial.correlation_px;
  EXPECT_EQ(render(one, 2), render(twice, 2));
  NoiseParams two = one;
  two.axial.correlation_cols_px = 2.5;
  two.axial.low_share = 0.5;
  const std::vector<float> a = render(two, 1);
  EXPECT_EQ(a, render(two, 3));
  EXPECT_NE(a, render(one, 1));
  // A white pixel-scale term under a low-frequency one.
  two.axial.correlation_px = 0;
  two.axial.correlation_cols_px = 0;
  EXPECT_EQ(render(two, 1), render(two, 2));
  two.axial.correlation_cols_px = 1;
  const std::string e = test::error_of<std::invalid_argument>([&] { (void)SensorNoise(two, camera); });
  EXPECT_NE(e.find("noise.axial.correlation_cols_px = 1"), std::string::npos) << e;
  EXPECT_NE(e.find("needs correlation_px > 0"), std::string::npos) << e;
}

// The Matern-5/2 kernel (issue 20): ranges 4 px along rows and 7 px along columns. On a
// fronto-parallel plate, without other noise: sigma is the model's, and the correlation at
// lag L along each direction is (1 + x + x^2 / 3) exp(-x), x = sqrt(5) L / r, with that
// direction's range r; the field is the same for any thread count and is not the Gaussian's.
TEST(SensorNoise, MaternFieldHasItsSigmaAndEachDirectionsCorrelation) {
  constexpr double kSigma = 0.002;  // [m]
  constexpr double kRhoTol = 0.04;  // seen: within 0.02 at every lag (4 frames of a smooth field)
  NoiseParams n = axial_only(kSigma);
  n.axial.kernel = AxialKernel::matern52;
  n.axial.correlation_px = 4.0;
  n.axial.correlation_cols_px = 7.0;
  constexpr int kLags = 8, kBorder = 24;  // away from the image border by the reach, 3 x 7 px
  const PlateField f = plate_field(n, kLags, kBorder);
  EXPECT_NEAR(f.sigma, kSigma, kStageSigmaRelTol * kSigma);
  const auto matern = [](int l, double r) {
    const double x = std::sqrt(5.0) * l / r;
    return (1 + x + x * x / 3) * std::exp(-x);
  };
  for (int l = 1; l <= kLags; ++l) {
    EXPECT_NEAR(f.rows[l], matern(l, 4.0), kRhoTol) << "along rows, lag " << l;
    EXPECT_NEAR(f.cols[l], matern(l, 7.0), kRhoTol) << "along columns, lag " << l;
  }
  // (A Gaussian of the same widths reads 0.83 and 0.57 at lag 6, against the Matern's 0.61
  // along columns and 0.28 along rows: the bands above tell them apart.) The same bits on 1
  // and 3 threads, and another field than the Gaussian's.
  EXPECT_EQ(plate_depth(n, 9, 0, 1), f.first);
  EXPECT_EQ(plate_depth(n, 9, 0, 3), f.first);
  NoiseParams gauss = n;
  gauss.axial.kernel = AxialKernel::gaussian;
  EXPECT_NE(plate_depth(gauss, 9, 0, 2), f.first);
  // Under 3 px the sampled filter no longer gives the covariance (0.1 off at 1 px): refused.
  NoiseParams short_range = n;
  short_range.axial.correlation_cols_px = 2;
  const std::string e = test::error_of<std::invalid_argument>([&] { short_range.validate(); });
  EXPECT_NE(e.find("noise.axial.correlation_cols_px = 2: must be 0 or >= 3 with kernel matern52"),
            std::string::npos)
      << e;
  gauss.axial.correlation_cols_px = 2;
  EXPECT_NO_THROW(gauss.validate());
}

TEST(SensorNoise, RejectsAnInputOfTheWrongSize) {
  const CameraParams camera;
  Plate plate(camera.intrinsics, 0.6);
  plate.lit.pop_back();
  SensorNoise noise(NoiseParams::sr300(), camera);
  io::DepthImage depth;
  std::vector<float> depth_m;
  try {
    noise.apply(plate.input(), 1, 1, 1, depth, depth_m);
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("input image of 307199 values for 307200 pixels"),
              std::string::npos) << e.what();
  }
  NoiseParams bad = NoiseParams::sr300();
  bad.axial.a = -1;
  EXPECT_THROW(SensorNoise(bad, camera), std::invalid_argument);
}

TEST(SensorCull, ReachableHoldsEveryPixelWhoseRayMeetsTheBox) {
  const CameraParams camera;
  const io::Intrinsics& K = camera.intrinsics;
  const Eigen::Isometry3d X_CW = camera.X_WC.inverse();
  std::mt19937_64 rng(11);  // seeded: the same points every run
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int box = 0; box < 20; ++box) {
    const Eigen::Vector3d c(0.1 + 0.3 * unit(rng), -0.1 + 0.2 * unit(rng), 0.35 + 0.2 * unit(rng));
    const Eigen::Vector3d half(0.01 + 0.1 * unit(rng), 0.01 + 0.1 * unit(rng), 0.01 + 0.1 * unit(rng));
    const PixelRect r = reachable(c - half, c + half, camera.X_WC, K, 0.0);
    ASSERT_FALSE(r.empty());
    for (int k = 0; k < 200; ++k) {
      const Eigen::Vector3d p_W = c + half.cwiseProduct(Eigen::Vector3d(2 * unit(rng) - 1, 2 * unit(rng) - 1,
                                                                       2 * unit(rng) - 1));
      const Eigen::Vector3d p_C = X_CW * p_W;
      ASSERT_GT(p_C.z(), 0);
      const double u = K.fx * p_C.x() / p_C.z() + K.cx, v = K.fy * p_C.y() / p_C.z() + K.cy;
      if (u < 0 || v < 0 || u > K.width - 1 || v > K.height - 1) continue;
      // The pixels around the point's projection must all be cast.
      EXPECT_TRUE(r.contains(static_cast<int>(std::floor(u)), static_cast<int>(std::floor(v))));
      EXPECT_TRUE(r.contains(static_cast<int>(std::ceil(u)), static_cast<int>(std::ceil(v))));
    }
  }
  // Nothing: empty; a corner behind the camera or a distorted camera: the whole image.
  EXPECT_TRUE(reachable(Eigen::Vector3d(1, 1, 1), Eigen::Vector3d(0, 0, 0), camera.X_WC, K, 0).empty());
  const PixelRect all{{0, K.width - 1, 0, K.height - 1}};
  const Eigen::Vector3d eye = camera.X_WC.translation();
  EXPECT_EQ(reachable(eye - Eigen::Vector3d::Constant(0.1), eye + Eigen::Vector3d::Constant(0.1),
                      camera.X_WC, K, 0), all);
  io::Intrinsics distorted = K;
  distorted.model = io::Distortion::inverse_brown_conrady;
  EXPECT_EQ(reachable(Eigen::Vector3d(0.2, -0.05, 0.4), Eigen::Vector3d(0.3, 0.05, 0.5), camera.X_WC,
                      distorted, 0), all);
  // grown() clips to the image and keeps an empty rectangle empty.
  EXPECT_EQ(grown(PixelRect{{2, 5, 0, 3}}, 4, K.width, K.height), (PixelRect{{0, 9, 0, 7}}));
  EXPECT_TRUE(grown(PixelRect{}, 4, K.width, K.height).empty());
}

TEST(SensorCull, ShadowCasterMayBlockEveryRayThatMeetsTheBox) {
  // A projector at the origin looking along +z; a box 0.4 m away.
  const Eigen::AlignedBox3d box(Eigen::Vector3d(-0.05, -0.02, 0.38), Eigen::Vector3d(0.05, 0.02, 0.42));
  const ShadowCaster caster = ShadowCaster::of(box, Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero());
  ASSERT_FALSE(caster.everywhere);
  std::mt19937_64 rng(12);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  int blocked = 0, free = 0;
  for (int k = 0; k < 4000; ++k) {
    // Points from 0.2 to 0.8 m; a segment to the projector meets the box when some of its
    // samples lie inside.
    const Eigen::Vector3d p(-0.15 + 0.3 * unit(rng), -0.1 + 0.2 * unit(rng), 0.2 + 0.6 * unit(rng));
    bool meets = false;
    for (int s = 1; s <= 400 && !meets; ++s) meets = box.contains(p * (s / 400.0));
    const bool may = caster.may_block(p.cast<float>());
    if (meets) {
      EXPECT_TRUE(may) << p.transpose();
    }
    (meets ? blocked : free) += 1;
  }
  EXPECT_GT(blocked, 100);
  EXPECT_GT(free, 100);
  // Nearer than the box, or outside its silhouette: never blocked.
  EXPECT_FALSE(caster.may_block(Eigen::Vector3f(0, 0, 0.3F)));
  EXPECT_FALSE(caster.may_block(Eigen::Vector3f(0.3F, 0, 0.6F)));
  // An absent body blocks nothing.
  EXPECT_FALSE(ShadowCaster::of(Eigen::AlignedBox3d(), Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero())
                   .may_block(Eigen::Vector3f(0, 0, 1)));
}

}  // namespace
}  // namespace linksight::sim
