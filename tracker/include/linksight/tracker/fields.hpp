#pragma once
/// @file Parameter structs list their fields once (as Drake's `Serialize(Archive*)`), and
/// that list drives reading files, writing them, the range checks of `validate()` and the
/// key names in errors.
///
/// A struct lists its fields in a member template, by the key a file uses:
///
///     template <class Archive> void fields(Archive& ar) {
///       ar("a_m", a, fields::at_least(0));          // [m], >= 0
///       ar("theta_cap_deg", theta_cap, fields::deg(fields::in_hi_open(0, 90)));
///       ar("enabled", enabled);
///       ar("axial", axial);                         // a struct with its own fields()
///       ar("mode", mode, parse_mode);               // an enum: to_string + its parser
///     }
///
/// and its `validate()` calls `fields::check(*this, "noise")` before its cross-field rules.
/// An archive is any class with those call operators: `fields::Checker` below, the YAML
/// reader and writer (sim/yaml), the JSON echo (tools/params_json.hpp). Archives that only read the
/// values (check, write) visit a const object through `const_cast`; they never assign.

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <string_view>
#include <type_traits>

#include "linksight/tracker/format.hpp"

namespace linksight::fields {

/// What a number field may hold, in the units of its key (degrees for `*_deg`).
struct Rule {
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
  bool lo_open = false;  ///< value must be > lo (not >=)
  bool hi_open = false;  ///< value must be < hi (not <=)
  /// The value in code is the value in the file times this (pi/180 for `*_deg` keys).
  double scale = 1.0;
};
[[nodiscard]] constexpr Rule any() { return {}; }
[[nodiscard]] constexpr Rule at_least(double lo) { return {.lo = lo}; }
[[nodiscard]] constexpr Rule above(double lo) { return {.lo = lo, .lo_open = true}; }
[[nodiscard]] constexpr Rule in(double lo, double hi) { return {.lo = lo, .hi = hi}; }
/// (lo, hi]
[[nodiscard]] constexpr Rule in_lo_open(double lo, double hi) {
  return {.lo = lo, .hi = hi, .lo_open = true};
}
/// [lo, hi)
[[nodiscard]] constexpr Rule in_hi_open(double lo, double hi) {
  return {.lo = lo, .hi = hi, .hi_open = true};
}
/// The same rule, the file in degrees and the code in radians.
[[nodiscard]] constexpr Rule deg(Rule r) {
  r.scale = 3.14159265358979323846 / 180.0;
  return r;
}

/// "must be in [0, 0.1]", "must be >= 0", "must be > 0", ...
[[nodiscard]] std::string describe(const Rule& rule);
/// Whether `value` (in code units: the bounds are multiplied by rule.scale, as a reader
/// multiplies the file's value) obeys the rule; NaN and Inf never do.
[[nodiscard]] bool obeys(const Rule& rule, double value);

/// A field that breaks a rule. `key()` is the key path from the struct that was checked
/// ("axial.a_m" in NoiseParams), so a reader can point at the line that set it; what()
/// is "<root>.<key> = <value>: <rule>".
class FieldError : public std::invalid_argument {
 public:
  FieldError(std::string key, std::string value, std::string rule, std::string root = "");
  [[nodiscard]] const std::string& key() const { return key_; }
  [[nodiscard]] const std::string& value() const { return value_; }
  [[nodiscard]] const std::string& rule() const { return rule_; }
  /// The name of the struct that was checked ("noise"); empty inside a nested check.
  [[nodiscard]] const std::string& root() const { return root_; }
  /// The same error one struct further out: key "parent.key".
  [[nodiscard]] FieldError within(const std::string& parent) const;
  /// The same error, what() prefixed by the checked struct's name.
  [[nodiscard]] FieldError rooted(const std::string& root) const;

 private:
  std::string key_, value_, rule_, root_;
};

/// An archive that accepts anything: to detect a struct that lists its fields.
struct Probe {
  template <class... A>
  void operator()(A&&...) {}
};
/// A struct that lists its fields.
template <class T>
concept HasFields = requires(T& t, Probe& p) { t.fields(p); };
/// A field's parser: text in, value out (throws std::invalid_argument naming the choices).
template <class P>
concept Parser = std::is_invocable_v<P, std::string_view>;

/// Checks every number against its rule (values in the key's units) and that vectors are
/// finite; throws FieldError naming the key path.
class Checker {
 public:
  void operator()(const char* key, double& v, Rule rule = {}) const {
    if (!obeys(rule, v)) throw FieldError(key, format_shortest(v, rule.scale), describe(rule));
  }
  template <class I>
    requires std::is_integral_v<I> && (!std::is_same_v<I, bool>)
  void operator()(const char* key, I& v, Rule rule = {}) const {
    if (!obeys(rule, static_cast<double>(v)))
      throw FieldError(key, std::to_string(v), describe(rule));
  }
  void operator()(const char*, bool&) const {}
  template <class E, Parser Parse>
  void operator()(const char*, E&, Parse) const {}
  void operator()(const char* key, Eigen::Vector3d& v) const {
    if (!v.allFinite()) throw FieldError(key, "[...]", "must be finite");
  }
  void operator()(const char* key, Eigen::Isometry3d& X) const {
    if (!X.matrix().allFinite()) throw FieldError(key, "[...]", "must be finite");
  }
  template <std::size_t N>
  void operator()(const char* key, std::array<double, N>& v) const {
    for (double x : v)
      if (!std::isfinite(x)) throw FieldError(key, "[...]", "must be finite");
  }
  template <HasFields T>
  void operator()(const char* key, T& sub) const {
    try {
      sub.fields(const_cast<Checker&>(*this));
    } catch (const FieldError& e) {
      throw e.within(key);
    }
  }
};

/// Runs the Checker over `x`'s fields; a FieldError's what() starts with `root`.
template <HasFields T>
void check(const T& x, const std::string& root) {
  Checker c;
  try {
    const_cast<T&>(x).fields(c);
  } catch (const FieldError& e) {
    throw e.rooted(root);
  }
}

/// A cross-field rule broken: throws FieldError for `key` with its value.
[[noreturn]] void fail(const std::string& root, const std::string& key, double value,
                       const std::string& rule);

}  // namespace linksight::fields
