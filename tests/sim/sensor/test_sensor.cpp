// The simulated depth camera (sim/sensor): geometry, noise statistics, projector
// shadow, occlusion bookkeeping, thread independence and parameter errors.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "linksight/io/error.hpp"
#include "linksight/sim/scene.hpp"
#include "linksight/sim/sensor.hpp"
#include "test_support.hpp"

namespace linksight::sim {
namespace {

constexpr double kSurfaceTol = 0.05e-3;  // [m] issue 5: labelled pixels on the analytic surface
constexpr double kSigmaRelTol = 0.10;    // issue 5: noise sigma within 10% of the model
constexpr double kShadowTolPx = 1.0;     // issue 5: shadow width within one pixel

// Component frames of a straight chain leaving (0, 0, 0.5) along +x (frame K's z).
std::vector<Eigen::Isometry3d> straight_chain(const ComponentGeometry& g) {
  return test::straight_chain_frames(g);
}

// A camera 0.5 m in front of the straight chain (on -y), looking at its middle.
SensorParams side_view(NoiseParams noise) {
  SensorParams p;
  p.camera.X_WC = look_at({0.25, -0.5, 0.5}, {0.25, 0.0, 0.5});
  p.noise = noise;
  return p;
}

// A wide plate whose camera-facing side is the plane z = depth of a camera at the origin
// of W looking along W's +z (X_WC = identity).
BackgroundObject wall_at(double depth, double half_thickness = 0.01) {
  BackgroundObject b;
  b.shape.kind = Shape::Kind::box;
  b.shape.half_extents = Eigen::Vector3d(3.0, 3.0, half_thickness);
  b.X_WO.translation() = Eigen::Vector3d(0, 0, depth + half_thickness);
  return b;
}

SensorParams frontal(NoiseParams noise) {
  SensorParams p;
  p.camera.X_WC = Eigen::Isometry3d::Identity();
  p.noise = noise;
  return p;
}

ComponentGeometry one_component() {
  ComponentGeometry g;
  g.count = 1;
  return g;
}

// Noise-free depth in float metres back-projects onto the analytic ball or neck surface,
// with a pinhole camera and with the SR300's inverse Brown-Conrady model: the sensor casts
// through the same deprojection the reader of real depth PNGs uses.
class SensorSurface : public ::testing::TestWithParam<io::Distortion> {};

TEST_P(SensorSurface, NoiseOffLabelledPixelsLieOnTheAnalyticSurface) {
  const ComponentGeometry g;
  SensorParams params = side_view(NoiseParams::off());
  params.camera.intrinsics.model = GetParam();
  if (GetParam() != io::Distortion::none)
    params.camera.intrinsics.coeffs = {0.14, -0.05, 0.003, 0.004, 0.01};  // SR300-like
  Sensor sensor(params, g);
  const auto X_WK = straight_chain(g);
  const DepthFrame f = sensor.render(X_WK, 0.0, 1, 0);
  const io::Intrinsics& K = sensor.params().camera.intrinsics;
  const Eigen::Isometry3d X_WC = sensor.params().camera.X_WC;
  std::vector<int> seen(g.count, 0);
  double worst = 0;
  for (int v = 0; v < f.height; ++v) {
    for (int u = 0; u < f.width; ++u) {
      const std::size_t i = static_cast<std::size_t>(v) * f.width + u;
      if (f.label[i] >= g.count) continue;
      ASSERT_GT(f.depth_m[i], 0.0F) << "labelled pixel without depth at " << u << "," << v;
      const int c = f.label[i];
      ++seen[c];
      const Eigen::Vector3d p_K = X_WK[c].inverse() * (X_WC * K.deproject(u, v, f.depth_m[i]));
      const double ball = std::abs(p_K.norm() - g.ball_radius);
      const double s = std::clamp(p_K.z(), 0.0, g.neck_length);
      const double neck = std::abs((p_K - Eigen::Vector3d(0, 0, s)).norm() - g.neck_radius);
      worst = std::max(worst, std::min(ball, neck));
    }
  }
  EXPECT_LT(worst, kSurfaceTol);
  for (int c = 0; c < g.count; ++c) EXPECT_GT(seen[c], 100) << "component " << c;
  EXPECT_DOUBLE_EQ(f.link_occluded_fraction, 0.0);
}
INSTANTIATE_TEST_SUITE_P(Distortion, SensorSurface,
                         ::testing::Values(io::Distortion::none,
                                           io::Distortion::inverse_brown_conrady),
                         [](const auto& p) {
                           return p.param == io::Distortion::none ? "pinhole"
                                                                      : "inverse_brown_conrady";
                         });

TEST(Sensor, NoiseOffPlaneGivesItsDepthUpToQuantization) {
  NoiseParams noise = NoiseParams::off();
  noise.quantize = true;
  for (double z : {0.3, 0.5, 0.8}) {
    Sensor sensor(frontal(noise), one_component(), {}, {wall_at(z)});
    std::vector<Eigen::Isometry3d> away(1, Eigen::Isometry3d::Identity());
    away[0].translation() = Eigen::Vector3d(0, 0, -5);  // behind the camera
    const DepthFrame f = sensor.render(away, 0.0, 1, 0);
    const double unit = sensor.params().camera.intrinsics.depth_scale;
    for (std::size_t i = 0; i < f.label.size(); ++i) {
      ASSERT_EQ(f.label[i], kLabelBackground);
      ASSERT_NEAR(f.depth_clean_m[i], z, 1e-6);
      ASSERT_LE(std::abs(f.depth.data[i] * unit - z), 0.5 * unit + 1e-9);
      ASSERT_FLOAT_EQ(f.depth_m[i], static_cast<float>(f.depth.data[i] * unit));
    }
  }
}

// Embree reports an instance's normal in the instance's frame: a tilted plate must
// still give its true incidence angle.
TEST(Sensor, IncidenceAngleOfATiltedPlate) {
  for (double deg : {0.0, 30.0, 60.0}) {
    BackgroundObject b = wall_at(0.0);
    b.X_WO = Eigen::Isometry3d::Identity();
    b.X_WO.linear() = Eigen::AngleAxisd(deg * std::numbers::pi / 180, Eigen::Vector3d::UnitY())
                          .toRotationMatrix();
    b.X_WO.translation() = Eigen::Vector3d(0, 0, 0.6);
    Sensor sensor(frontal(NoiseParams::off()), one_component(), {}, {b});
    std::vector<Eigen::Isometry3d> away(1, Eigen::Isometry3d::Identity());
    away[0].translation() = Eigen::Vector3d(0, 0, -5);
    const DepthFrame f = sensor.render(away, 0.0, 1, 0);
    const io::Intrinsics& K = sensor.params().camera.intrinsics;
    // The pixel whose ray is the optical axis: (cx, cy) are integers here.
    const std::size_t i = static_cast<std::size_t>(K.cy) * f.width + static_cast<std::size_t>(K.cx);
    EXPECT_NEAR(f.incidence[i] * 180 / std::numbers::pi, deg, 0.01);
  }
}

// Axial noise: per-pixel residuals of a fronto-parallel plane have the model's sigma.
TEST(Sensor, PlaneNoiseMatchesTheModelSigma) {
  NoiseParams noise = NoiseParams::off();
  noise.axial.enabled = true;
  noise.quantize = true;
  for (double z : {0.3, 0.5, 0.8}) {
    Sensor sensor(frontal(noise), one_component(), {}, {wall_at(z)});
    std::vector<Eigen::Isometry3d> away(1, Eigen::Isometry3d::Identity());
    away[0].translation() = Eigen::Vector3d(0, 0, -5);
    const DepthFrame f = sensor.render(away, 0.0, 7, 3);
    double sum = 0, sum2 = 0, model2 = 0;
    long n = 0;
    for (std::size_t i = 0; i < f.label.size(); ++i) {
      if (f.depth.data[i] == 0) continue;
      const double r = f.depth_m[i] - f.depth_clean_m[i];
      const double s = noise.axial.sigma(f.depth_clean_m[i], f.incidence[i]);
      sum += r;
      sum2 += r * r;
      model2 += s * s;
      ++n;
    }
    ASSERT_GT(n, 300000);
    const double sigma = std::sqrt(sum2 / n - (sum / n) * (sum / n));
    const double model = std::sqrt(model2 / n);
    EXPECT_NEAR(sigma / model, 1.0, kSigmaRelTol) << "z = " << z;
    EXPECT_NEAR(sum / n, 0.0, 0.05 * model) << "z = " << z << ": biased";
  }
}

// Projector shadow behind a vertical edge: f b (1/z1 - 1/z2) pixels wide, on the side
// away from the projector.
TEST(Sensor, ProjectorShadowWidthMatchesTheBaselineGeometry) {
  const double z1 = 0.5, z2 = 0.8;
  for (double baseline : {0.05, -0.03}) {
    NoiseParams noise = NoiseParams::off();
    noise.shadow.enabled = true;
    noise.shadow.baseline = baseline;
    // A plate at z1 covering x >= 0 (baseline > 0) or x <= 0 (baseline < 0).
    BackgroundObject plate;
    plate.shape.half_extents = Eigen::Vector3d(0.5, 0.5, 0.002);
    plate.X_WO.translation() = Eigen::Vector3d(baseline > 0 ? 0.5 : -0.5, 0, z1 + 0.002);
    Sensor sensor(frontal(noise), one_component(), {}, {plate, wall_at(z2)});
    std::vector<Eigen::Isometry3d> away(1, Eigen::Isometry3d::Identity());
    away[0].translation() = Eigen::Vector3d(0, 0, -5);
    const DepthFrame f = sensor.render(away, 0.0, 1, 0);
    const io::Intrinsics& K = sensor.params().camera.intrinsics;
    const double expected = K.fx * std::abs(baseline) * (1 / z1 - 1 / z2);
    for (int v : {100, 245, 400}) {
      int shadow = 0;
      for (int u = 0; u < f.width; ++u) {
        const std::size_t i = static_cast<std::size_t>(v) * f.width + u;
        if (f.depth.data[i] == 0) {
          ++shadow;
          // On the far surface, on the side of the edge away from the projector.
          EXPECT_NEAR(f.depth_clean_m[i], z2, 1e-4);
          EXPECT_EQ(u < K.cx, baseline > 0) << "u = " << u;
        }
      }
      EXPECT_NEAR(shadow, expected, kShadowTolPx) << "baseline " << baseline << ", row " << v;
    }
  }
}

// A box hiding exactly components 4, 5 and 6 of a chain of spheres (no necks, so the
// gaps between balls give the box's edges room), and a second box covering the image
// right of ball 8's centre: half of it.
TEST(Sensor, OccludedFractionOfABoxOverTheMiddleThreeBalls) {
  ComponentGeometry g;
  g.neck_length = 0.0;
  const double p = g.pitch;
  const double y_box = -0.2;  // the boxes' front faces, 0.3 m from the camera, 0.5 from the chain
  const double scale = (y_box + 0.5) / 0.5;
  auto at_box = [&](double x_chain) { return 0.25 + (x_chain - 0.25) * scale; };
  Occluder middle;
  middle.shape.half_extents =
      Eigen::Vector3d(0.5 * (at_box(6.5 * p) - at_box(3.5 * p)), 0.0005, 0.05);
  middle.path = BaseTrajectory(
      {{0.0, Eigen::Isometry3d(Eigen::Translation3d(0.5 * (at_box(6.5 * p) + at_box(3.5 * p)),
                                                    y_box + 0.0005, 0.5))}},
      {});
  Occluder half;
  half.shape.half_extents = Eigen::Vector3d(0.05, 0.0005, 0.05);
  half.path = BaseTrajectory(
      {{0.0, Eigen::Isometry3d(Eigen::Translation3d(at_box(8 * p) + 0.05, y_box + 0.0005, 0.5))}},
      {});
  Sensor sensor(side_view(NoiseParams::off()), g, {middle, half});
  const DepthFrame f = sensor.render(straight_chain(g), 0.0, 1, 0);
  for (int c = 0; c < g.count; ++c) {
    ASSERT_GT(f.visible_px_unoccluded[c], 100) << "component " << c;
    if (c >= 4 && c <= 6) {
      EXPECT_EQ(f.visible_px[c], 0) << "component " << c;
      EXPECT_DOUBLE_EQ(f.occluded_fraction[c], 1.0) << "component " << c;
    } else if (c == 8) {
      EXPECT_NEAR(f.occluded_fraction[c], 0.5, 0.03);
    } else if (c < 8) {
      EXPECT_EQ(f.visible_px[c], f.visible_px_unoccluded[c]) << "component " << c;
      EXPECT_DOUBLE_EQ(f.occluded_fraction[c], 0.0) << "component " << c;
    } else {
      EXPECT_DOUBLE_EQ(f.occluded_fraction[c], 1.0) << "component " << c;
    }
  }
  bool occluder_labels = false;
  for (std::uint8_t l : f.label) occluder_labels |= l == kLabelOccluder0 || l == kLabelOccluder0 + 1;
  EXPECT_TRUE(occluder_labels);
}

// The edge model on a plate at 0.5 m before a wall at 0.8 m (no other noise term, so
// every change is the edge model's): far-side pixels 1 and 2 px from the near surface
// are dropped at band_p1 and band_p2, near-side edge pixels at p_drop, and kept ones fly
// with p_flying to a position within flying_position +- flying_spread. Several hundred
// pixels per class: probabilities within 0.07 (3.5 binomial sigma at 200 pixels).
// A steep but continuous surface is no discontinuity: with every edge drop certain, a
// plate whose depth grows by 0.6-0.9 of the jump per pixel (two pixels: more than the
// jump) keeps every pixel away from its border.
TEST(Sensor, EdgeModelLeavesSteepSlopesAlone) {
  NoiseParams noise = NoiseParams::off();
  noise.edges.enabled = true;
  noise.edges.jump = 0.002;
  noise.edges.band_p1 = noise.edges.band_p2 = noise.edges.p_drop = 1.0;
  BackgroundObject plate;
  plate.shape.half_extents = Eigen::Vector3d(0.08, 0.08, 0.002);
  // Turned 52 deg about the camera's y: 1.2-1.6 mm more depth per pixel at 0.5 m.
  plate.X_WO = Eigen::Translation3d(0.0, 0.0, 0.5) * Eigen::AngleAxisd(0.9, Eigen::Vector3d::UnitY());
  Sensor sensor(frontal(noise), one_component(), {}, {plate});
  std::vector<Eigen::Isometry3d> away(1, Eigen::Isometry3d::Identity());
  away[0].translation() = Eigen::Vector3d(0, 0, -5);
  const DepthFrame f = sensor.render(away, 0.0, 3, 0);
  const int W = f.width;
  long inside = 0, dropped = 0;
  double steepest = 0;
  for (int v = 200; v < 280; ++v)
    for (int u = 260; u < 380; ++u) {
      const std::size_t i = static_cast<std::size_t>(v) * W + u;
      bool interior = f.depth_clean_m[i] > 0;
      for (int d = -3; d <= 3 && interior; ++d)
        interior = f.depth_clean_m[i + d] > 0 && f.depth_clean_m[i + static_cast<std::size_t>(d * W)] > 0;
      if (!interior) continue;
      ++inside;
      dropped += f.depth.data[i] == 0;
      steepest = std::max(steepest, std::abs(double(f.depth_clean_m[i + 1]) - f.depth_clean_m[i]));
    }
  ASSERT_GT(inside, 1000);
  EXPECT_GT(steepest, 0.5 * noise.edges.jump);  // two pixels do differ by more than the jump
  EXPECT_LT(steepest, noise.edges.jump);
  EXPECT_EQ(dropped, 0);
}

TEST(Sensor, EdgeModelBandsAndFlyingPixels) {
  const double z1 = 0.5, z2 = 0.8;
  NoiseParams noise = NoiseParams::off();
  noise.edges.enabled = true;
  noise.edges.band_p1 = 0.7;
  noise.edges.band_p2 = 0.4;
  noise.edges.p_drop = 0.3;
  noise.edges.p_flying = 0.5;
  noise.edges.flying_position = 0.4;
  noise.edges.flying_spread = 0.1;
  BackgroundObject plate;
  plate.shape.half_extents = Eigen::Vector3d(0.1, 0.1, 0.002);
  plate.X_WO.translation() = Eigen::Vector3d(0.0, 0.0, z1 + 0.002);
  Sensor sensor(frontal(noise), one_component(), {}, {plate, wall_at(z2)});
  std::vector<Eigen::Isometry3d> away(1, Eigen::Isometry3d::Identity());
  away[0].translation() = Eigen::Vector3d(0, 0, -5);
  long far1 = 0, far1_drop = 0, far2 = 0, far2_drop = 0, near = 0, near_drop = 0;
  long kept = 0, flying = 0;
  for (std::uint64_t frame = 0; frame < 4; ++frame) {
    const DepthFrame f = sensor.render(away, 0.0, 3, frame);
    const int W = f.width, H = f.height;
    auto clean = [&](int u, int v) { return f.depth_clean_m[static_cast<std::size_t>(v) * W + u]; };
    for (int v = 2; v < H - 2; ++v)
      for (int u = 2; u < W - 2; ++u) {
        const std::size_t i = static_cast<std::size_t>(v) * W + u;
        const bool dropped = f.depth.data[i] == 0;
        const double z0 = clean(u, v);
        bool n1 = false, n2 = false, is_near = false;
        const int du[4] = {-1, 1, 0, 0}, dv[4] = {0, 0, -1, 1};
        for (int k = 0; k < 4; ++k) {
          const double z1n = clean(u + du[k], v + dv[k]), z2n = clean(u + 2 * du[k], v + 2 * dv[k]);
          n1 = n1 || (z1n > 0 && z0 - z1n > 0.02);
          n2 = n2 || (z1n > 0 && std::abs(z1n - z0) <= 0.02 && z2n > 0 && z1n - z2n > 0.02);
          is_near = is_near || z1n <= 0 || z1n - z0 > 0.02;
        }
        if (n1) {
          ++far1, far1_drop += dropped;
        } else if (n2) {
          ++far2, far2_drop += dropped;
        } else if (is_near) {
          ++near, near_drop += dropped;
          if (!dropped) {
            ++kept;
            const double pos = (f.depth_m[i] - z1) / (z2 - z1);
            if (pos > 0.05) {
              ++flying;
              EXPECT_GE(pos, 0.3 - 0.01);
              EXPECT_LE(pos, 0.5 + 0.01);
            }
          }
        } else if (z0 > 0) {
          EXPECT_FALSE(dropped) << "away from edges nothing is dropped";
        }
      }
  }
  ASSERT_GT(far1, 200);
  ASSERT_GT(far2, 200);
  ASSERT_GT(kept, 200);
  EXPECT_NEAR(double(far1_drop) / far1, 0.7, 0.07);
  EXPECT_NEAR(double(far2_drop) / far2, 0.4, 0.07);
  EXPECT_NEAR(double(near_drop) / near, 0.3, 0.07);
  EXPECT_NEAR(double(flying) / kept, 0.5, 0.07);
}

// edges.drop_steps: the camera never reports two 4-neighbours more than the jump apart
// (docs/sensor.md), so the farther of such a pair is dropped, from the reported image as it
// was before any drop, and nothing else changes; the same for any thread count.
TEST(Sensor, DropStepsLeavesNoReportedNeighboursAJumpApart) {
  NoiseParams noise = NoiseParams::off();
  noise.edges.enabled = true;
  noise.edges.band_p1 = 0.3;  // many far pixels kept next to the near surface
  noise.edges.p_drop = 0.3;
  noise.edges.p_flying = 0.5;
  BackgroundObject plate;
  plate.shape.half_extents = Eigen::Vector3d(0.1, 0.1, 0.002);
  plate.X_WO.translation() = Eigen::Vector3d(0.0, 0.0, 0.502);
  std::vector<Eigen::Isometry3d> away(1, Eigen::Isometry3d::Identity());
  away[0].translation() = Eigen::Vector3d(0, 0, -5);
  const auto render = [&](bool drop, int threads) {
    NoiseParams n = noise;
    n.edges.drop_steps = drop;
    SensorParams p = frontal(n);
    p.threads = threads;
    Sensor sensor(p, one_component(), {}, {plate, wall_at(0.8)});
    return sensor.render(away, 0.0, 3, 2);  // seed 3, frame 2
  };
  const DepthFrame before = render(false, 1), after = render(true, 1), after3 = render(true, 3);
  EXPECT_EQ(after.depth.data, after3.depth.data);
  EXPECT_EQ(after.depth_m, after3.depth_m);
  const int W = before.width, H = before.height;
  const double unit = frontal(noise).camera.intrinsics.depth_scale;
  // Reported neighbours more than the jump apart, and whether each pixel has a nearer one.
  const auto steps = [&](const std::vector<std::uint16_t>& d, std::vector<bool>* farther) {
    long pairs = 0;
    for (int v = 0; v < H; ++v)
      for (int u = 0; u < W; ++u) {
        const std::size_t i = static_cast<std::size_t>(v) * W + u;
        if (d[i] == 0) continue;
        const int du[4] = {-1, 1, 0, 0}, dv[4] = {0, 0, -1, 1};
        for (int k = 0; k < 4; ++k) {
          const int uu = u + du[k], vv = v + dv[k];
          if (uu < 0 || uu >= W || vv < 0 || vv >= H) continue;
          const int b = d[static_cast<std::size_t>(vv) * W + uu];
          if (b == 0 || (d[i] - b) * unit <= noise.edges.jump) continue;
          ++pairs;
          if (farther != nullptr) (*farther)[i] = true;
        }
      }
    return pairs;
  };
  std::vector<bool> farther(before.depth.data.size(), false);
  ASSERT_GT(steps(before.depth.data, &farther), 100) << "the case must have such pairs";
  EXPECT_EQ(steps(after.depth.data, nullptr), 0);
  long dropped = 0;
  for (std::size_t i = 0; i < farther.size(); ++i) {
    if (farther[i]) {
      EXPECT_EQ(after.depth.data[i], 0) << "pixel " << i;
      EXPECT_EQ(after.depth_m[i], 0.0F) << "pixel " << i;
      ++dropped;
    } else {
      EXPECT_EQ(after.depth.data[i], before.depth.data[i]) << "pixel " << i;
      EXPECT_EQ(after.depth_m[i], before.depth_m[i]) << "pixel " << i;
    }
  }
  EXPECT_GT(dropped, 100);
}

class SensorThreads : public ::testing::TestWithParam<double> {};

void expect_same_images_for_any_thread_count(const NoiseParams& noise) {
  const ComponentGeometry g;
  SensorParams p = side_view(noise);
  BackgroundObject table;
  table.shape.half_extents = Eigen::Vector3d(1.0, 1.0, 0.01);
  table.X_WO.translation() = Eigen::Vector3d(0.25, 0.3, 0.3);
  p.threads = 1;
  Sensor one(p, g, {}, {table});
  p.threads = 2;
  Sensor two(p, g, {}, {table});
  const auto X = straight_chain(g);
  for (std::uint64_t frame : {0u, 5u}) {
    const DepthFrame a = one.render(X, 0.0, 42, frame);
    const DepthFrame b = two.render(X, 0.0, 42, frame);
    EXPECT_EQ(a.depth.data, b.depth.data);
    EXPECT_EQ(a.depth_m, b.depth_m);
    EXPECT_EQ(a.label, b.label);
  }
  // A different frame or seed draws different noise.
  EXPECT_NE(one.render(X, 0.0, 42, 0).depth.data, one.render(X, 0.0, 42, 1).depth.data);
  EXPECT_NE(one.render(X, 0.0, 42, 0).depth.data, one.render(X, 0.0, 43, 0).depth.data);
}

// The pixel-scale axial field white or correlated (the blurred field is built in parallel
// too), in the one-field model and beside the two-scale sr300's low-frequency field.
TEST_P(SensorThreads, SameImagesForAnyThreadCount) {
  for (const bool two_scale : {false, true}) {
    SCOPED_TRACE(two_scale ? "sr300" : "sr300-one-field");
    NoiseParams noise = two_scale ? NoiseParams::sr300() : NoiseParams::sr300_one_field();
    noise.axial.correlation_px = GetParam();
    noise.axial.correlation_cols_px = 0;  // (a white term has no width)
    expect_same_images_for_any_thread_count(noise);
  }
}

INSTANTIATE_TEST_SUITE_P(Sensor, SensorThreads, ::testing::Values(0.0, 1.5),
                         [](const ::testing::TestParamInfo<double>& i) {
                           return i.param > 0 ? std::string("Correlated") : std::string("White");
                         });

// Correlated noise keeps its sigma (unit variance after the blur) and correlates
// neighbours as exp(-L^2 / 4 s^2): on a fronto-parallel plate, without other noise.
TEST(Sensor, CorrelatedNoiseHasItsSigmaAndCorrelation) {
  NoiseParams noise = NoiseParams::off();
  noise.axial.enabled = true;
  noise.axial.a = 0.002;
  noise.axial.c = 0.0;
  noise.axial.k_theta = 0.0;
  noise.axial.correlation_px = 1.5;
  SensorParams p = side_view(noise);
  BackgroundObject plate;
  plate.shape.half_extents = Eigen::Vector3d(2.0, 0.01, 2.0);
  plate.X_WO.translation() = Eigen::Vector3d(0.25, 0.3, 0.5);  // its face 0.79 m from the camera
  Sensor sensor(p, ComponentGeometry{}, {}, {plate});
  std::vector<Eigen::Isometry3d> away(11, Eigen::Isometry3d(Eigen::Translation3d(0, 0, -10)));
  double s2 = 0, c1 = 0, c2 = 0;
  long n = 0;
  for (std::uint64_t frame = 0; frame < 3; ++frame) {
    const DepthFrame f = sensor.render(away, 0.0, 7, frame);
    const int W = f.width;
    for (int v = 100; v < 380; ++v)
      for (int u = 100; u < 540; ++u) {
        const auto at = [&](int uu) {
          const std::size_t i = static_cast<std::size_t>(v) * W + uu;
          return static_cast<double>(f.depth_m[i]) - f.depth_clean_m[i];
        };
        s2 += at(u) * at(u);
        c1 += at(u) * at(u + 1);
        c2 += at(u) * at(u + 2);
        ++n;
      }
  }
  EXPECT_NEAR(std::sqrt(s2 / n), 0.002, kSigmaRelTol * 0.002);
  EXPECT_NEAR(c1 / s2, std::exp(-1.0 / (4 * 1.5 * 1.5)), 0.03);
  EXPECT_NEAR(c2 / s2, std::exp(-4.0 / (4 * 1.5 * 1.5)), 0.03);
}

// Culling skips pixels whose rays provably miss: the images must not change. A small
// occluder over part of the chain and a sphere beside it, with jitter on; the chain is
// bent and shifted so that its bounds are not the whole image.
TEST(Sensor, CullingLeavesTheImagesUnchanged) {
  const ComponentGeometry g;
  SensorParams p = side_view(NoiseParams::sr300());
  p.noise.lateral.sigma_px = 2.0;  // a wide jitter margin
  Occluder hand;
  hand.shape.half_extents = Eigen::Vector3d(0.03, 0.01, 0.03);
  hand.path = BaseTrajectory(
      {{0.0, Eigen::Isometry3d(Eigen::Translation3d(0.2, -0.15, 0.5))},
       {1.0, Eigen::Isometry3d(Eigen::Translation3d(0.45, -0.15, 0.55))}},
      {});
  BackgroundObject ball;
  ball.shape.kind = Shape::Kind::sphere;
  ball.shape.radius = 0.02;
  ball.X_WO.translation() = Eigen::Vector3d(-0.05, 0.1, 0.6);
  std::vector<Eigen::Isometry3d> X = straight_chain(g);
  for (std::size_t k = 0; k < X.size(); ++k)
    X[k].translation() += Eigen::Vector3d(0.0, 0.0, 0.001 * static_cast<double>(k * k));
  p.cull = false;
  Sensor reference(p, g, {hand}, {ball});
  p.cull = true;
  Sensor culled(p, g, {hand}, {ball});
  for (const double t : {0.0, 0.5, 1.0}) {
    const DepthFrame a = reference.render(X, t, 7, 3);
    const DepthFrame b = culled.render(X, t, 7, 3);
    EXPECT_EQ(a.depth.data, b.depth.data) << "t = " << t;
    EXPECT_EQ(a.label, b.label) << "t = " << t;
    EXPECT_EQ(a.visible_px, b.visible_px) << "t = " << t;
    EXPECT_EQ(a.visible_px_unoccluded, b.visible_px_unoccluded) << "t = " << t;
    EXPECT_GT(b.link_occluded_fraction, 0.0) << "t = " << t;
  }
}

// RenderExtent::chain_only: inside the box it reports, every image is the whole-frame
// render's, bit for bit; outside, every pixel is a miss. The README demo's scene with
// everything that reads neighbours or draws per pixel switched on: the 2-px edge band,
// flying pixels, correlated noise, jitter, shadows, and the hand in front of the link.
TEST(Sensor, ChainOnlyRenderMatchesTheWholeFrameInsideItsBox) {
  Scene scene = load_scene(std::filesystem::path(LINKSIGHT_SCENE_DIR) / "default.yaml");
  scene.noise.axial.correlation_px = 1.5;
  scene.noise.edges.band_p2 = 0.8;
  scene.noise.edges.p_flying = 0.3;
  const auto world = make_world(scene);
  const Truth truth = world->truth();
  auto sensor = make_sensor(scene, 2);
  RenderExtent extent;
  extent.chain_only = true;
  extent.margin_px = 3;
  // The one-field model, and the two-term anisotropic one (its low-frequency field reaches
  // 21 px beyond the box along columns).
  Scene two_terms = scene;
  two_terms.noise.axial.correlation_cols_px = 2.5;
  two_terms.noise.axial.low_share = 0.5;
  two_terms.noise.axial.low_rows_px = 5;
  two_terms.noise.axial.low_cols_px = 7;
  auto two_term_sensor = make_sensor(two_terms, 2);
  // And the two-scale structure: the low field on a grid of 2 px, without the angle term.
  Scene two_scales = two_terms;
  two_scales.noise.axial.low_stride_px = 2;
  two_scales.noise.axial.low_angle_term = false;
  auto two_scale_sensor = make_sensor(two_scales, 2);
  for (const auto& [t, cam] : {std::pair{0.0, sensor.get()}, std::pair{6.5, sensor.get()},
                               std::pair{6.5, two_term_sensor.get()},
                               std::pair{6.5, two_scale_sensor.get()}}) {
    // The hand is in front of the link at 6.5 s.
    SCOPED_TRACE(std::to_string(t) + (cam == two_term_sensor.get()    ? " s, two terms"
                                      : cam == two_scale_sensor.get() ? " s, two scales"
                                                                      : " s"));
    const DepthFrame a = cam->render(truth.X_WK, t, 7, 3);
    const DepthFrame b = cam->render(truth.X_WK, t, 7, 3, extent);
    EXPECT_EQ(a.rendered, (PixelBox{0, a.width - 1, 0, a.height - 1}));
    const PixelBox& box = b.rendered;
    ASSERT_FALSE(box.empty());
    EXPECT_LT((box.u1 - box.u0 + 1) * (box.v1 - box.v0 + 1), a.width * a.height / 2)
        << "the box is not the link's";
    int link_px = 0, hits_outside = 0;
    for (int v = 0; v < a.height; ++v) {
      for (int u = 0; u < a.width; ++u) {
        const std::size_t i = static_cast<std::size_t>(v) * a.width + u;
        if (box.contains(u, v)) {
          ASSERT_EQ(a.depth.data[i], b.depth.data[i]) << u << ", " << v;
          ASSERT_EQ(a.depth_m[i], b.depth_m[i]) << u << ", " << v;
          ASSERT_EQ(a.label[i], b.label[i]) << u << ", " << v;
          ASSERT_EQ(a.depth_clean_m[i], b.depth_clean_m[i]) << u << ", " << v;
        } else {
          EXPECT_GE(a.label[i], kLabelOccluder0) << "a link pixel outside the box";
          hits_outside += b.depth.data[i] != 0;
        }
        link_px += a.label[i] < kLabelOccluder0;
      }
    }
    EXPECT_GT(link_px, 1000);
    EXPECT_EQ(hits_outside, 0);
    EXPECT_EQ(a.visible_px, b.visible_px);
    EXPECT_EQ(a.visible_px_unoccluded, b.visible_px_unoccluded);
    EXPECT_EQ(a.link_occluded_fraction, b.link_occluded_fraction);
    if (t > 6) {
      EXPECT_GT(b.link_occluded_fraction, 0.05);
    }
  }
  // The edge model's 2-px reach: a near plate whose edge falls 1.6 px right of the box.
  // The box's last column then has a nearer surface 2 px away (its 2-px band); a cast
  // area only 1 px wider than the box would not see it.
  {
    const PixelBox box = sensor->render(truth.X_WK, 0.0, 7, 3, extent).rendered;
    const io::Intrinsics& K = scene.camera.intrinsics;
    const Eigen::Isometry3d& X_WC = scene.camera.X_WC;
    constexpr double kFront = 0.4, kHalfThickness = 0.0001;  // [m]: camera z of its face
    const Eigen::Vector3d edge_C = K.deproject(box.u1 + 1.6, 0.5 * (box.v0 + box.v1), kFront);
    Occluder plate;  // axes along the camera's
    plate.shape.half_extents = Eigen::Vector3d(0.05, 0.4, kHalfThickness);
    Eigen::Isometry3d X_WO = X_WC;
    X_WO.translation() = X_WC * (edge_C + Eigen::Vector3d(0.05, 0.0, kHalfThickness));
    plate.path = BaseTrajectory({{0.0, X_WO}, {10.0, X_WO}}, {});
    Scene with_plate = scene;
    with_plate.occluders.push_back(plate);
    auto plated = make_sensor(with_plate, 2);
    const DepthFrame a = plated->render(truth.X_WK, 0.0, 7, 3);
    const DepthFrame b = plated->render(truth.X_WK, 0.0, 7, 3, extent);
    ASSERT_EQ(b.rendered, box);
    int plate_px = 0, dropped_at_edge = 0;
    for (int v = box.v0; v <= box.v1; ++v) {
      const std::size_t i = static_cast<std::size_t>(v) * a.width;
      const std::uint8_t l = a.label[i + box.u1 + 2];
      plate_px += l >= kLabelOccluder0 && l < kLabelBackground;
      dropped_at_edge += a.depth.data[i + box.u1] == 0;
      for (int u = box.u0; u <= box.u1; ++u)
        ASSERT_EQ(a.depth.data[i + u], b.depth.data[i + u]) << "with the plate, " << u << ", " << v;
    }
    EXPECT_GT(plate_px, (box.v1 - box.v0) / 2) << "the plate should start 2 px right of the box";
    EXPECT_GT(dropped_at_edge, plate_px / 4) << "its 2-px band should drop pixels in the box";
  }
  extent.margin_px = -1;
  const std::string e = test::error_of<std::invalid_argument>(
      [&] { (void)sensor->render(truth.X_WK, 0.0, 7, 3, extent); });
  EXPECT_NE(e.find("margin_px = -1"), std::string::npos) << e;
}

// Shadow culling skips shadow rays that cannot be blocked: by the moving bodies' and each
// background body's silhouettes seen from the projector, and a convex body never shadows
// its own lit side. Here the chain and a hand shadow a wall behind them, a box on the
// floor shadows the wall too, and a wide baseline makes the shadows wide.
TEST(Sensor, ShadowCullingLeavesTheImagesUnchanged) {
  const ComponentGeometry g;
  SensorParams p = side_view(NoiseParams::sr300());
  p.noise.shadow.baseline = 0.12;
  Occluder hand;
  hand.shape.half_extents = Eigen::Vector3d(0.03, 0.01, 0.03);
  hand.path = BaseTrajectory(
      {{0.0, Eigen::Isometry3d(Eigen::Translation3d(0.1, -0.2, 0.5))},
       {1.0, Eigen::Isometry3d(Eigen::Translation3d(0.4, -0.2, 0.52))}},
      {});
  BackgroundObject wall, floor, block;
  wall.shape.half_extents = Eigen::Vector3d(1.0, 0.01, 1.0);
  wall.X_WO.translation() = Eigen::Vector3d(0.25, 0.12, 0.5);
  floor.shape.half_extents = Eigen::Vector3d(1.0, 0.5, 0.01);
  floor.X_WO.translation() = Eigen::Vector3d(0.25, 0.0, 0.38);
  block.shape.half_extents = Eigen::Vector3d(0.03, 0.03, 0.03);
  block.X_WO.translation() = Eigen::Vector3d(0.05, 0.0, 0.42);
  const std::vector<Eigen::Isometry3d> X = straight_chain(g);
  p.cull = false;
  Sensor reference(p, g, {hand}, {wall, floor, block});
  p.cull = true;
  Sensor culled(p, g, {hand}, {wall, floor, block});
  p.noise.shadow.enabled = false;
  Sensor unshadowed(p, g, {hand}, {wall, floor, block});
  for (const double t : {0.0, 0.5, 1.0}) {
    const DepthFrame a = reference.render(X, t, 7, 3);
    const DepthFrame b = culled.render(X, t, 7, 3);
    const DepthFrame c = unshadowed.render(X, t, 7, 3);
    EXPECT_EQ(a.depth.data, b.depth.data) << "t = " << t;
    EXPECT_EQ(a.label, b.label) << "t = " << t;
    // The shadows are there to be culled wrongly: many pixels lose their depth to them.
    long shadowed = 0;
    for (std::size_t i = 0; i < a.depth.data.size(); ++i)
      shadowed += a.depth.data[i] == 0 && c.depth.data[i] != 0;
    EXPECT_GT(shadowed, 2000) << "t = " << t;
  }
}

template <class F>
void expect_invalid(F&& make, const std::string& needle) {
  try {
    make();
    ADD_FAILURE() << "no error; expected one naming " << needle;
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

TEST(Sensor, BadParametersAreNamed) {
  const ComponentGeometry g;
  const struct {
    void (*spoil)(SensorParams&);
    const char* names;
  } cases[] = {
      {[](SensorParams& p) { p.camera.intrinsics.fx = 0; }, "fx"},
      {[](SensorParams& p) { p.camera.z_min = p.camera.z_max = 1.5; }, "z_min"},
      {[](SensorParams& p) { p.camera.intrinsics.width = 0; }, "width"},
      {[](SensorParams& p) { p.noise.edges.p_drop = 1.5; }, "edges.p_drop"},
  };
  for (const auto& c : cases) {
    expect_invalid([&] {
      SensorParams p;
      c.spoil(p);
      Sensor s(p, g);
    }, c.names);
  }
  expect_invalid([&] {
    Occluder o;
    o.shape.kind = Shape::Kind::mesh;
    o.shape.mesh = "/nonexistent/hand.obj";
    Sensor s(SensorParams{}, g, {o});
  }, "/nonexistent/hand.obj");
  EXPECT_THROW(
      {
        Occluder o;
        o.shape.kind = Shape::Kind::mesh;
        o.shape.mesh = "/nonexistent/hand.obj";
        Sensor s(SensorParams{}, g, {o});
      },
      io::InputError);
  Sensor s(SensorParams{}, g);
  expect_invalid([&] { (void)s.render({}, 0.0, 1, 0); }, "component poses");
}

}  // namespace
}  // namespace linksight::sim
