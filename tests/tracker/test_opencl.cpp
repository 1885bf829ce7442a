// OpenCL-specific behaviour (equivalence with serial is in test_backend.cpp). CI installs
// PoCL, so a CPU OpenCL device is always present here.
#include <gtest/gtest.h>

#include <algorithm>
#include <functional>

#include "linksight/tracker/opencl.hpp"
#include "linksight/tracker/tracker.hpp"
#include "test_support.hpp"

namespace linksight {
namespace {

Cloud cloud(std::uint64_t seed, int samples = 3000) {
  sim::SurfaceSampling s;
  s.noise_sigma = 0.002;
  s.seed = seed;
  s.samples_per_ball = samples;
  return sim::sample_visible_surface(test::test_chain(sim::ChainShape::c_shape), {}, s);
}

TEST(OpenCL, ListsAtLeastOneDeviceWithWhatTheBackEndNeeds) {
  LINKSIGHT_SKIP_IF_UNBUILT(test::BackendCase{BackendKind::opencl});
  const auto devices = opencl_devices();
  ASSERT_FALSE(devices.empty()) << "no OpenCL device: tools/setup.sh installs pocl-opencl-icd";
  bool usable = false;
  for (const auto& d : devices) {
    EXPECT_FALSE(d.name.empty());
    EXPECT_NE(d.version.find("OpenCL"), std::string::npos) << d.version;
    EXPECT_GT(d.compute_units, 0u);
    EXPECT_GT(d.global_memory_bytes, 0u);
    usable |= d.int64_atomics;
  }
  EXPECT_TRUE(usable);
  const bool gpu = std::any_of(devices.begin(), devices.end(), [](const OpenCLDevice& d) {
    return d.type == "GPU" && d.int64_atomics;
  });
  EXPECT_EQ(auto_backend(), gpu ? BackendKind::opencl : BackendKind::openmp);
}

// Fixed-point sums: the result is the same integer whatever the work-group size.
TEST(OpenCL, BitIdenticalForAnyWorkGroupSize) {
  LINKSIGHT_SKIP_IF_UNBUILT(test::BackendCase{BackendKind::opencl});
  const test::Soa pts(cloud(4, 6000));
  std::vector<float> q;
  for (const auto& n : test::test_chain(sim::ChainShape::c_shape)) {
    for (int a = 0; a < 3; ++a) q.push_back(static_cast<float>(n[a]));
  }
  std::vector<std::int64_t> first_sum;
  std::vector<std::int64_t> first_count;
  std::vector<std::int32_t> first_assoc;
  for (ClAccumulation acc_kind : {ClAccumulation::reduction, ClAccumulation::atomic}) {
    for (std::size_t wg : {1u, 16u, 64u, 100u, 256u}) {
      OpenCLOptions o;
      o.accumulation = acc_kind;
      o.work_group_size = wg;
      auto b = make_backend(BackendKind::opencl, 0, o);
      b->set_points(pts.view());
      Accumulation acc;
      b->associate(q, acc);
      const auto a = b->association();
      if (first_sum.empty()) {
        first_sum = acc.sum;
        first_count = acc.count;
        first_assoc.assign(a.begin(), a.end());
        continue;
      }
      SCOPED_TRACE("work group " + std::to_string(wg));
      EXPECT_EQ(acc.sum, first_sum);  // exact
      EXPECT_EQ(acc.count, first_count);
      EXPECT_TRUE(std::equal(a.begin(), a.end(), first_assoc.begin()));
    }
  }
}

TEST(OpenCL, TwoTrackersAliveAtOnce) {
  LINKSIGHT_SKIP_IF_UNBUILT(test::BackendCase{BackendKind::opencl});
  TrackerParams p = test::paper_params();
  p.backend = BackendKind::opencl;
  Tracker a(p), b(p);
  Tracker ref(test::paper_params());
  for (int f = 0; f < 3; ++f) {
    const Cloud ca = cloud(10 + f), cb = cloud(20 + f, 1500);
    const FrameResult ra = a.step(ca), rb = b.step(cb);
    const FrameResult rr = ref.step(ca);
    EXPECT_EQ(ra.nodes, rr.nodes);  // bit-identical to serial
    EXPECT_EQ(rb.n_points, cb.size());
    EXPECT_GT(ra.device_time_s, 0.0);
    EXPECT_LE(ra.device_time_s, ra.time_s * 1.5);
  }
}

TEST(OpenCL, BuildFailureCarriesTheBuildLog) {
  LINKSIGHT_SKIP_IF_UNBUILT(test::BackendCase{BackendKind::opencl});
  const std::string e = test::error_of(
      [] { check_opencl_build("kernel void k(global int* a) { a[0] = undeclared_name; }"); });
  EXPECT_NE(e.find("kernel build failed"), std::string::npos) << e;
  EXPECT_NE(e.find("undeclared_name"), std::string::npos) << e;  // the compiler's own words
  EXPECT_NO_THROW(check_opencl_build("kernel void k(global int* a) { a[0] = 1; }"));
}

TEST(OpenCL, SelectionErrorsSayWhatExists) {
  LINKSIGHT_SKIP_IF_UNBUILT(test::BackendCase{BackendKind::opencl});
  OpenCLOptions o;
  o.device = "no-such-device-xyz";
  const std::string none = test::error_of([&] { (void)make_backend(BackendKind::opencl, 0, o); });
  EXPECT_NE(none.find("no device matches 'no-such-device-xyz'"), std::string::npos) << none;
  EXPECT_NE(none.find(opencl_devices().front().name), std::string::npos) << none;
  OpenCLOptions p;
  p.platform = 99;
  const std::string platform = test::error_of([&] { (void)make_backend(BackendKind::opencl, 0, p); });
  EXPECT_NE(platform.find("--cl-platform 99 does not exist"), std::string::npos) << platform;
  OpenCLOptions w;
  w.work_group_size = 5000;
  EXPECT_THROW(w.validate(), std::invalid_argument);
  const std::string wide = test::error_of([&] { w.validate(); });
  EXPECT_NE(wide.find("work_group_size = 5000: must be <= 4096"), std::string::npos) << wide;
  // Device names match case-insensitively.
  OpenCLOptions c;
  c.device = opencl_devices().front().name.substr(0, 4);
  for (char& ch : c.device) ch = static_cast<char>(std::toupper(static_cast<unsigned char>(ch)));
  EXPECT_NO_THROW((void)make_backend(BackendKind::opencl, 0, c));
}

}  // namespace
}  // namespace linksight
