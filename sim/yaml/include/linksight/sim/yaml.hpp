#pragma once
/// @file The one YAML layer, for scene files and sweep grids: loading with file:line
/// errors, `--set` overrides, typed reads that name the key, and the archives that read
/// and write a parameter struct from its one field list (linksight/tracker/fields.hpp).
/// Ranges are not checked here: a struct's validate() does that, and `validated` turns
/// its fields::FieldError into an error at the key's line. Private to sim/scene and
/// sim/sweep (it exposes yaml-cpp).

#include <yaml-cpp/yaml.h>

#include <Eigen/Geometry>

#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <ostream>
#include <set>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "linksight/io/error.hpp"
#include "linksight/tracker/fields.hpp"
#include "linksight/tracker/format.hpp"
#include "linksight/tracker/limits.hpp"

namespace linksight::sim::yaml {

/// A `--set key.path=value` override: the key path and the text given.
struct Override {
  std::string key, value;
  std::string flag = "--set";  ///< where it came from, for messages: "--set" or "--axis"
};

// kMaxFileBytes: linksight/tracker/limits.hpp.

/// Parses a YAML file. Throws io::InputError "<file>: cannot open <what>",
/// "<file>: N bytes, more than a <what> may have (kMaxFileBytes)" or
/// "<file>:<line>: malformed YAML: <why>".
[[nodiscard]] YAML::Node load_file(const std::filesystem::path& file, const std::string& what);

/// Applies "a.b[0].c=value" to `root`: intermediate mappings are created, list elements
/// must exist, the value is parsed as YAML. Throws io::InputError naming `file` and the
/// override.
Override apply_override(const std::string& file, YAML::Node& root, const std::string& text,
                        const std::string& flag = "--set");

/// Typed reads from YAML nodes with "<file>:<line>: <key>: <problem>" errors (or
/// "<file>: --set <override>: ..." for a key an override set).
class Reader {
 public:
  explicit Reader(std::string file, std::vector<Override> overrides = {})
      : file_(std::move(file)), overrides_(std::move(overrides)) {}

  [[noreturn]] void fail(const YAML::Node& node, const std::string& key,
                         const std::string& what) const;
  /// `map` is a mapping whose keys are all plain names in `keys`.
  void only(const YAML::Node& map, const std::string& where,
            const std::set<std::string>& keys) const;
  /// A key's text; a key that is not a plain scalar is an error.
  [[nodiscard]] std::string key_text(const YAML::Node& key, const std::string& where) const;
  /// The number at `n` (named `key` in errors).
  [[nodiscard]] double number(const YAML::Node& n, const std::string& key) const;
  /// A number that is a whole value in [lo, hi) (hi exclusive, so that 2^64 is a bound
  /// a double holds exactly).
  [[nodiscard]] double integer(const YAML::Node& n, const std::string& key, double lo,
                               double hi_exclusive) const;
  [[nodiscard]] std::string text(const YAML::Node& n, const std::string& key) const;
  [[nodiscard]] bool boolean(const YAML::Node& n, const std::string& key) const;
  /// `count` numbers in a list.
  void numbers(const YAML::Node& n, const std::string& key, double* out, int count) const;
  [[nodiscard]] Eigen::Vector3d vec3(const YAML::Node& n, const std::string& key) const;
  /// A 4x4 row-major rigid transform (last row 0 0 0 1).
  [[nodiscard]] Eigen::Isometry3d transform(const YAML::Node& n, const std::string& key) const;

 private:
  std::string file_;
  std::vector<Override> overrides_;
};

/// The key path `where.key` ("noise" + "axial" -> "noise.axial"; "" + "seed" -> "seed").
[[nodiscard]] std::string join(const std::string& where, const std::string& key);
/// The node a dotted key path ("axial.a_m") leads to in `map`, or the deepest one found.
[[nodiscard]] YAML::Node node_at(const YAML::Node& map, const std::string& path);

/// Collects a struct's keys (to tell them from unknown ones).
class KeyLister {
 public:
  std::set<std::string> keys;
  template <class T, class... Rest>
  void operator()(const char* key, T&, Rest&&...) {
    keys.insert(key);
  }
};
template <fields::HasFields T>
[[nodiscard]] std::set<std::string> keys_of(const T& x) {
  KeyLister k;
  const_cast<T&>(x).fields(k);
  return std::move(k.keys);
}

/// Reads a struct's fields from a mapping: a key that is absent keeps the struct's value.
/// Checks types only (a number, a whole number, true/false, one of an enum's names).
class In {
 public:
  In(const Reader& r, const YAML::Node& map, std::string where)
      : r_(r), map_(map), where_(std::move(where)) {}
  void operator()(const char* key, double& v, fields::Rule rule = {}) const {
    if (const YAML::Node n = map_[key]) v = r_.number(n, join(where_, key)) * rule.scale;
  }
  template <class I>
    requires std::is_integral_v<I> && (!std::is_same_v<I, bool>)
  void operator()(const char* key, I& v, fields::Rule = {}) const {
    // The type's range as doubles, exactly: [-2^digits, 2^digits) (digits without the sign).
    if (const YAML::Node n = map_[key])
      v = static_cast<I>(r_.integer(
          n, join(where_, key),
          std::is_signed_v<I> ? -std::ldexp(1.0, std::numeric_limits<I>::digits) : 0.0,
          std::ldexp(1.0, std::numeric_limits<I>::digits)));
  }
  void operator()(const char* key, bool& v) const {
    if (const YAML::Node n = map_[key]) v = r_.boolean(n, join(where_, key));
  }
  template <class E, fields::Parser Parse>
  void operator()(const char* key, E& v, Parse parse) const {
    if (const YAML::Node n = map_[key]) {
      const std::string name = join(where_, key);
      const std::string t = r_.text(n, name);
      try {
        v = parse(t);
      } catch (const std::invalid_argument& e) {
        r_.fail(n, name, e.what());
      }
    }
  }
  void operator()(const char* key, Eigen::Vector3d& v) const {
    if (const YAML::Node n = map_[key]) v = r_.vec3(n, join(where_, key));
  }
  template <std::size_t N>
  void operator()(const char* key, std::array<double, N>& v) const {
    if (const YAML::Node n = map_[key]) r_.numbers(n, join(where_, key), v.data(), N);
  }
  void operator()(const char* key, Eigen::Isometry3d& v) const {
    if (const YAML::Node n = map_[key]) v = r_.transform(n, join(where_, key));
  }
  template <fields::HasFields T>
  void operator()(const char* key, T& sub) const {
    if (const YAML::Node n = map_[key]) {
      const std::string name = join(where_, key);
      r_.only(n, name, keys_of(sub));
      In child(r_, n, name);
      sub.fields(child);
    }
  }

 private:
  const Reader& r_;
  YAML::Node map_;
  std::string where_;
};

/// Runs `validate` (a struct's validate()) for the block `map` at `where`; a
/// fields::FieldError becomes an error at its key's line ("camera.fx = 0: must be in
/// [0.001, 100000]"), any other std::invalid_argument an error about the block.
template <class F>
void validated(const Reader& r, const YAML::Node& map, const std::string& where, F&& validate) {
  try {
    validate();
  } catch (const fields::FieldError& e) {
    const YAML::Node at = node_at(map, e.key());
    r.fail(at, join(where, e.key()), "= " + e.value() + ": " + e.rule());
  } catch (const std::invalid_argument& e) {
    r.fail(map, where, e.what());
  }
}

/// Reads block `map` (at key path `where`) into `x`: its keys must be x's fields or
/// `extra` (read by the caller).
template <fields::HasFields T>
void read(const Reader& r, const YAML::Node& map, const std::string& where, T& x,
          const std::set<std::string>& extra = {}) {
  std::set<std::string> keys = keys_of(x);
  keys.insert(extra.begin(), extra.end());
  r.only(map, where, keys);
  In in(r, map, where);
  x.fields(in);
}

/// Writes a struct's fields as block-style YAML, numbers as the shortest text that reads
/// back to the same double (degrees for `*_deg` keys).
class Out {
 public:
  Out(std::ostream& os, int indent) : os_(os), indent_(indent) {}
  void operator()(const char* key, double& v, fields::Rule rule = {}) {
    line(key) << format_shortest(v, rule.scale) << "\n";
  }
  template <class I>
    requires std::is_integral_v<I> && (!std::is_same_v<I, bool>)
  void operator()(const char* key, I& v, fields::Rule = {}) {
    line(key) << std::to_string(v) << "\n";
  }
  void operator()(const char* key, bool& v) { line(key) << (v ? "true" : "false") << "\n"; }
  template <class E, fields::Parser Parse>
  void operator()(const char* key, E& v, Parse) {
    line(key) << to_string(v) << "\n";
  }
  void operator()(const char* key, Eigen::Vector3d& v) { list(key, v.data(), 3); }
  template <std::size_t N>
  void operator()(const char* key, std::array<double, N>& v) {
    list(key, v.data(), N);
  }
  void operator()(const char* key, Eigen::Isometry3d& X) {
    double m[16];
    for (int i = 0; i < 16; ++i) m[i] = X.matrix()(i / 4, i % 4);
    list(key, m, 16);
  }
  template <fields::HasFields T>
  void operator()(const char* key, T& sub) {
    os_ << std::string(indent_, ' ') << key << ":\n";
    Out child(os_, indent_ + 2);
    sub.fields(child);
  }

 private:
  std::ostream& line(const char* key) { return os_ << std::string(indent_, ' ') << key << ": "; }
  void list(const char* key, const double* v, std::size_t n);
  std::ostream& os_;
  int indent_;
};

/// `key:` and then x's fields indented by indent + 2.
template <fields::HasFields T>
void write(std::ostream& os, const char* key, const T& x, int indent = 0) {
  Out out(os, indent);
  out(key, const_cast<T&>(x));
}

}  // namespace linksight::sim::yaml
