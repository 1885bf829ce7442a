#include "linksight/io/chain_json.hpp"

#include <nlohmann/json.hpp>

namespace linksight::io {
namespace {

// Numbers only: ComponentGeometry's fields are.
struct Out {
  nlohmann::json& j;
  template <class T>
  void operator()(const char* key, T& v, fields::Rule = {}) {
    j[key] = v;
  }
};

}  // namespace

std::string chain_json(const ComponentGeometry& geometry, int indent) {
  nlohmann::json j = nlohmann::json::object();
  Out out{j};
  const_cast<ComponentGeometry&>(geometry).fields(out);
  return j.dump(indent);
}

}  // namespace linksight::io
