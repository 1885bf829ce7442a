// fields.hpp: one field list per parameter struct drives the range checks and the key
// names in errors; format.hpp: the one number formatter.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <numbers>
#include <set>
#include <string>
#include <vector>

#include "linksight/tracker/fields.hpp"
#include "linksight/tracker/format.hpp"
#include "linksight/tracker/tracker.hpp"

namespace linksight {
namespace {

// A struct as a user would add one: a nested block, an angle, an integer, an enum.
struct Inner {
  double angle = 10 * std::numbers::pi / 180;
  template <class A>
  void fields(A& ar) {
    ar("angle_deg", angle, fields::deg(fields::in(0, 45)));
  }
};
struct Toy {
  double length = 1.0;
  int count = 3;
  bool on = true;
  BackendKind backend = BackendKind::serial;
  Inner inner;
  template <class A>
  void fields(A& ar) {
    ar("length_m", length, fields::above(0));
    ar("count", count, fields::in(1, 10));
    ar("on", on);
    ar("backend", backend, parse_backend);
    ar("inner", inner);
  }
};

// Records the keys and values an archive is shown.
struct Recorder {
  std::vector<std::string> keys;
  template <class T, class... R>
  void operator()(const char* key, T& v, R&&...) {
    if constexpr (fields::HasFields<T>) {
      keys.push_back(std::string(key) + "{");
      v.fields(*this);
      keys.push_back("}");
    } else {
      keys.emplace_back(key);
    }
  }
};

TEST(Fields, OneListDrivesEveryArchive) {
  Toy t;
  Recorder r;
  t.fields(r);
  EXPECT_EQ(r.keys, (std::vector<std::string>{"length_m", "count", "on", "backend", "inner{",
                                              "angle_deg", "}"}));
  EXPECT_NO_THROW(fields::check(t, "toy"));
}

TEST(Fields, CheckNamesTheKeyPathValueAndRule) {
  Toy t;
  t.inner.angle = 50 * std::numbers::pi / 180;
  try {
    fields::check(t, "toy");
    FAIL() << "no error";
  } catch (const fields::FieldError& e) {
    EXPECT_EQ(e.key(), "inner.angle_deg");  // the path a file uses, not the C++ name
    EXPECT_EQ(e.value(), "50");             // in the key's units
    EXPECT_EQ(e.rule(), "must be in [0, 45]");
    EXPECT_EQ(e.root(), "toy");
    EXPECT_EQ(std::string(e.what()), "toy.inner.angle_deg = 50: must be in [0, 45]");
  }
  t = {};
  t.length = 0;
  EXPECT_THROW(fields::check(t, "toy"), fields::FieldError);  // above(0) is open
  t = {};
  t.length = std::nan("");
  EXPECT_THROW(fields::check(t, "toy"), fields::FieldError);  // NaN obeys no rule
  t = {};
  t.count = 11;
  EXPECT_THROW(fields::check(t, "toy"), std::invalid_argument);  // a FieldError is one
}

TEST(Fields, DescribeEveryRuleShape) {
  EXPECT_EQ(fields::describe(fields::in(0, 1)), "must be in [0, 1]");
  EXPECT_EQ(fields::describe(fields::in_lo_open(0, 1)), "must be in (0, 1]");
  EXPECT_EQ(fields::describe(fields::in_hi_open(0, 90)), "must be in [0, 90)");
  EXPECT_EQ(fields::describe(fields::at_least(0)), "must be >= 0");
  EXPECT_EQ(fields::describe(fields::above(1e-4)), "must be > 0.0001");
  EXPECT_EQ(fields::describe(fields::any()), "must be finite");
}

// A bound in degrees admits exactly the radians a reader makes of it (file * pi/180).
TEST(Fields, DegreeBoundsMatchWhatAReaderMakes) {
  const fields::Rule r = fields::deg(fields::in(0, 89.9));
  EXPECT_TRUE(fields::obeys(r, 89.9 * r.scale));
  EXPECT_FALSE(fields::obeys(r, std::nextafter(89.9 * r.scale, 2.0)));
  EXPECT_TRUE(fields::obeys(r, 0.0));
  EXPECT_FALSE(fields::obeys(r, -1e-300));
}

TEST(Format, ShortestReadsBackToTheSameBits) {
  for (double v : {0.1, 5.4e-05, 1.0 / 3.0, -0.063, 473.0, 1e300, 4.9e-324}) {
    const std::string s = format_shortest(v);
    EXPECT_EQ(std::strtod(s.c_str(), nullptr), v) << s;
  }
  EXPECT_EQ(format_shortest(0.1), "0.1");
  EXPECT_EQ(format_shortest(50), "50");
  EXPECT_EQ(format_shortest(1e6), "1000000");
  EXPECT_EQ(format_shortest(1e-4), "0.0001");
  EXPECT_EQ(format_shortest(5.4e-05), "5.4e-05");
  EXPECT_EQ(format_shortest(1e300), "1e+300");
  EXPECT_EQ(format_shortest(-0.063), "-0.063");
  EXPECT_EQ(format_shortest(std::nan("")), "nan");
  EXPECT_EQ(format_shortest(-INFINITY), "-inf");
  // With a scale: the shortest decimal that the scale maps back to the same value.
  const double k = std::numbers::pi / 180;
  EXPECT_EQ(format_shortest(80 * k, k), "80");
  EXPECT_EQ(format_shortest(89.9 * k, k), "89.9");
  // A value no decimal maps to exactly (as a reader maps it: d * pi/180) reads back
  // within one ulp; found by search so that the fallback is really taken.
  int unreachable = 0;
  for (double v = 0.001; v < 1.5 && unreachable < 5; v = std::nextafter(v * 1.37, 2.0)) {
    const double back = std::strtod(format_shortest(v, k).c_str(), nullptr) * k;
    if (back == v) continue;
    ++unreachable;
    EXPECT_LE(std::abs(back - v), std::nextafter(v, 2.0) - v) << v;
  }
  EXPECT_GT(unreachable, 0) << "no value took the fallback: the search proves nothing";
}

TEST(Format, FixedMatchesTheStreamsItReplaced) {
  EXPECT_EQ(format_fixed(3.14159265, 4), "3.1416");
  EXPECT_EQ(format_fixed(2.5, 0), "2");  // round half to even, as printf
  EXPECT_EQ(format_fixed(-0.00001, 2), "-0.00");
  EXPECT_EQ(format_fixed(1e300, 1).size(), 303u);
  EXPECT_EQ(format_fixed(INFINITY, 3), "nan");
}

// The parameter structs of the tracker list what a scene's tracker block holds.
TEST(Fields, TrackerParamsListTheSceneKeys) {
  TrackerParams p;
  Recorder r;
  p.fields(r);
  EXPECT_EQ(r.keys, (std::vector<std::string>{
                        "mode", "init", "poly_order", "max_points", "som_init", "backend",
                        "threads", "iterations", "tolerance_m", "chain_fit{", "max_iterations",
                        "huber_m", "max_distance_m", "tolerance_m", "reassociate_m", "coarse_stride",
                        "coarse_accept_m", "bend_sigma_deg",
                        "straight_sigma_deg", "misfit_inliers", "misfit_rms_m", "reinit_gain",
                        "free_space_below", "free_space_margin_m", "hidden_below", "}", "base_prior{", "enabled", "sigma_m", "sigma_deg", "}"}));
  ComponentGeometry g;
  Recorder rg;
  g.fields(rg);
  EXPECT_EQ(rg.keys.size(), 5u);
}

}  // namespace
}  // namespace linksight
