#pragma once
// Shared fixtures: synthetic chains with truth, views over clouds, named tolerances.

#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <initializer_list>
#include <limits>
#include <map>
#include <set>
#include <string>
#include <type_traits>
#include <vector>

#include "linksight/sim/synthetic_chain.hpp"
#include "linksight/tracker/backend.hpp"
#include "linksight/tracker/fields.hpp"
#include "linksight/tracker/init.hpp"
#include "linksight/tracker/opencl.hpp"
#include "linksight/tracker/tracker.hpp"

#include <gtest/gtest.h>

/// Skips the calling test, saying why, when back end case `c` is not in this build.
#define LINKSIGHT_SKIP_IF_UNBUILT(c)                                      \
  do {                                                                    \
    const std::string linksight_why = ::linksight::test::unbuilt_reason(c); \
    if (!linksight_why.empty()) GTEST_SKIP() << linksight_why;            \
  } while (0)

namespace linksight::test {

/// Component frames [W] of a straight chain leaving (0, 0, 0.5) along +x (each frame's z),
/// as the simulated camera's tests see it.
inline std::vector<Eigen::Isometry3d> straight_chain_frames(const ComponentGeometry& g) {
  std::vector<Eigen::Isometry3d> X(g.count, Eigen::Isometry3d::Identity());
  for (int c = 0; c < g.count; ++c) {
    X[c].linear() = Eigen::AngleAxisd(1.5707963267948966, Eigen::Vector3d::UnitY()).matrix();
    X[c].translation() = Eigen::Vector3d(c * g.pitch, 0.0, 0.5);
  }
  return X;
}

/// A cloud's finite points as separate arrays, for the functions that take PointsView.
struct Soa {
  std::vector<float> x, y, z;
  explicit Soa(const Cloud& c) {
    for (std::size_t i = 0; i < c.size(); ++i) {
      x.push_back(c.xyz[3 * i]);
      y.push_back(c.xyz[3 * i + 1]);
      z.push_back(c.xyz[3 * i + 2]);
    }
  }
  [[nodiscard]] PointsView view() const { return {x, y, z}; }
};

/// The standard test link: 11 components, r = 15 mm, pitch 45 mm, about 0.6 m from the
/// camera, its bending plane tilted 0.4 rad toward the camera.
inline Nodes test_chain(sim::ChainShape shape, double bend = 0.15,
                        const ComponentGeometry& g = {}) {
  Eigen::Isometry3d X_CB = Eigen::Isometry3d::Identity();
  X_CB.translation() = Eigen::Vector3d(-0.22, -0.02, 0.6);
  X_CB.linear() = Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitX()).toRotationMatrix();
  return sim::chain_nodes(g, sim::shape_bends(shape, g.count, bend), X_CB);
}

/// The test link hanging straight down the camera y axis, base at the top.
inline Nodes hanging_chain(double bend = 0.0, const ComponentGeometry& g = {}) {
  Eigen::Isometry3d X_CB = Eigen::Isometry3d::Identity();
  X_CB.translation() = Eigen::Vector3d(0.0, -0.22, 0.6);
  X_CB.linear() = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return sim::chain_nodes(g, sim::shape_bends(sim::ChainShape::c_shape, g.count, bend), X_CB);
}

/// One back end to test against the serial reference; OpenCL in both accumulations.
struct BackendCase {
  BackendKind kind = BackendKind::serial;
  ClAccumulation accumulation = ClAccumulation::reduction;
};
inline std::vector<BackendCase> all_backends() {
  return {{BackendKind::serial},
          {BackendKind::openmp},
          {BackendKind::opencl, ClAccumulation::reduction},
          {BackendKind::opencl, ClAccumulation::atomic}};
}
/// Every back end but the serial reference.
inline std::vector<BackendCase> other_backends() {
  auto all = all_backends();
  all.erase(all.begin());
  return all;
}
inline std::string case_name(const BackendCase& c) {
  std::string n(to_string(c.kind));
  if (c.kind == BackendKind::opencl)
    n += c.accumulation == ClAccumulation::atomic ? "_atomic" : "_reduction";
  return n;
}
/// Why this back end cannot run in this build; "" when it can.
inline std::string unbuilt_reason(const BackendCase& c) {
  if (c.kind == BackendKind::opencl && !opencl_built()) return kNoOpenCLBuild;
  return "";
}
/// gtest case name of a back-end parameter.
inline std::string backend_name(const ::testing::TestParamInfo<BackendCase>& p) {
  return case_name(p.param);
}
/// Make a back end of this case (OpenMP with 2 threads).
inline std::unique_ptr<Backend> make(const BackendCase& c) {
  OpenCLOptions o;
  o.accumulation = c.accumulation;
  return make_backend(c.kind, 2, o);
}
/// Paper mode's parameters: the tests of the SOM association and its back ends name the
/// paper's tracker (the default mode is chain-fit since issue 17).
inline TrackerParams paper_params() {
  TrackerParams p;
  p.mode = parse_mode("paper");
  return p;
}
/// Paper mode's parameters selecting this case (OpenMP with 2 threads).
inline TrackerParams params_for(const BackendCase& c) {
  TrackerParams p = paper_params();
  p.backend = c.kind;
  p.threads = 2;
  p.opencl.accumulation = c.accumulation;
  return p;
}

/// The modes as parse_mode's error lists them: "a, b or c", from the mode table.
inline std::string expected_modes() {
  const std::vector<std::string> names = mode_names();
  std::string s;
  for (std::size_t i = 0; i < names.size(); ++i)
    s += (i == 0 ? "" : i + 1 == names.size() ? " or " : ", ") + names[i];
  return s;
}

/// The message of the E that f() throws; "no error" when it throws nothing. Any other
/// exception propagates, so the test fails on it.
template <class E = std::exception, class F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const E& e) {
    return e.what();
  }
  return "no error";
}

/// Every number and flag a parameter struct lists (fields.hpp), by its key path
/// ("axial.a_m"), as the struct holds it (SI units, whatever the file's unit): so that a
/// test compares two parameter sets by the keys a scene file uses, not by a second list
/// of members.
class NumberFields {
 public:
  template <fields::HasFields T>
  explicit NumberFields(T x) {
    x.fields(*this);
  }
  template <class V, class... Rules>
  void operator()(const char* key, V& v, Rules&&...) {
    if constexpr (std::is_arithmetic_v<V>) {
      values_[prefix_ + key] = static_cast<double>(v);
    } else if constexpr (fields::HasFields<V>) {
      const std::string outer = prefix_;
      prefix_ += std::string(key) + ".";
      v.fields(*this);
      prefix_ = outer;
    } else {
      others_.insert(prefix_ + key);  // an enum, a string, a list: not compared as a number
    }
  }
  /// The value at `key`; a test failure naming it (and NaN) where the struct has no number
  /// or flag there.
  [[nodiscard]] double at(const std::string& key) const {
    const auto it = values_.find(key);
    if (it != values_.end()) return it->second;
    if (others_.count(key) != 0)
      ADD_FAILURE() << "field " << key << " is not a number or a flag";
    else
      ADD_FAILURE() << "no field " << key;
    return std::numeric_limits<double>::quiet_NaN();
  }

 private:
  std::string prefix_;
  std::map<std::string, double> values_;
  std::set<std::string> others_;
};

/// Expects each of `keys` (NumberFields' paths) in `fitted` within rel_tol of its value in
/// `expected`, naming the key where it is not.
template <fields::HasFields T>
void expect_fields_near(const T& fitted, const T& expected, std::initializer_list<const char*> keys,
                        double rel_tol) {
  const NumberFields f(fitted), e(expected);
  for (const char* key : keys) {
    const double want = e.at(key);
    if (std::isnan(want)) continue;  // at() has failed the test, naming the key
    EXPECT_NEAR(f.at(key), want, rel_tol * std::abs(want)) << key;
  }
}

/// A tracker's one-component slip after a re-initialization (node j on ball j - 1; see
/// docs/robustness.md): the worst frame measures 44-48 mm; 60 mm, which a slip of two
/// components would break [m].
inline constexpr double kSlipBand = 0.060;

/// The scratch directories this test process made, removed when it exits (kept when
/// LINKSIGHT_KEEP_SCRATCH is set, to look at after a failure).
struct ScratchDirs {
  std::vector<std::filesystem::path> dirs;
  ~ScratchDirs() {
    if (std::getenv("LINKSIGHT_KEEP_SCRATCH") != nullptr) return;
    std::error_code ec;
    for (const auto& d : dirs) std::filesystem::remove_all(d, ec);
  }
};
inline ScratchDirs& scratch_dirs() {
  static ScratchDirs dirs;
  return dirs;
}

/// A fresh, empty scratch directory for one test.
inline std::filesystem::path scratch_dir(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() /
                   ("linksight_test_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  scratch_dirs().dirs.push_back(dir);
  return dir;
}

}  // namespace linksight::test
