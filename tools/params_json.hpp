#pragma once
// A parameter struct as JSON, from its one field list (linksight/tracker/fields.hpp):
// the echo of the settings in a command's summary.json, under the scene file's keys.

#include <Eigen/Geometry>

#include <array>
#include <string>
#include <type_traits>

#include <nlohmann/json.hpp>

#include "format.hpp"
#include "linksight/tracker/fields.hpp"

namespace linksight::cli {

/// An archive (fields.hpp) that writes each field into a JSON object.
class JsonOut {
 public:
  explicit JsonOut(nlohmann::json& j) : j_(j) {}
  void operator()(const char* key, double& v, fields::Rule rule = {}) {
    j_[key] = json_number(v / rule.scale);
  }
  template <class I>
    requires std::is_integral_v<I>
  void operator()(const char* key, I& v, fields::Rule = {}) {
    j_[key] = v;
  }
  template <class E, fields::Parser Parse>
  void operator()(const char* key, E& v, Parse) {
    j_[key] = std::string(to_string(v));
  }
  void operator()(const char* key, Eigen::Vector3d& v) { j_[key] = {v.x(), v.y(), v.z()}; }
  template <std::size_t N>
  void operator()(const char* key, std::array<double, N>& v) {
    j_[key] = v;
  }
  void operator()(const char* key, Eigen::Isometry3d& X) {
    nlohmann::json m = nlohmann::json::array();
    for (int i = 0; i < 16; ++i) m.push_back(X.matrix()(i / 4, i % 4));
    j_[key] = m;
  }
  template <fields::HasFields T>
  void operator()(const char* key, T& sub) {
    JsonOut child(j_[key]);
    sub.fields(child);
  }

 private:
  nlohmann::json& j_;
};

/// x's fields as a JSON object.
template <fields::HasFields T>
nlohmann::json to_json(const T& x) {
  nlohmann::json j = nlohmann::json::object();
  JsonOut out(j);
  const_cast<T&>(x).fields(out);
  return j;
}

}  // namespace linksight::cli
