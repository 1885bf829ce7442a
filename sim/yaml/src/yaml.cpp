#include "linksight/sim/yaml.hpp"

#include <cmath>

#include "linksight/io/echo.hpp"

namespace linksight::sim::yaml {

YAML::Node load_file(const std::filesystem::path& path, const std::string& what) {
  const std::string file = path.string();
  // yaml-cpp holds about 110 bytes per byte of input: a file past the limit is refused
  // before it is parsed, not after gigabytes (issue 19, F5).
  std::error_code ec;
  // A FIFO would block the read, a device never end: only a regular file is read.
  if (std::filesystem::exists(path, ec) && !std::filesystem::is_regular_file(path, ec))
    throw io::InputError(file + ": not a regular file (a " + what + " must be one)");
  const std::uintmax_t bytes = std::filesystem::file_size(path, ec);
  if (!ec && bytes > kMaxFileBytes)
    throw io::InputError(file + ": " + std::to_string(bytes) + " bytes, more than a " + what +
                         " may have (" + std::to_string(kMaxFileBytes) + ")");
  try {
    return YAML::LoadFile(file);
  } catch (const YAML::BadFile&) {
    throw io::InputError(file + ": cannot open " + what);
  } catch (const YAML::ParserException& e) {
    throw io::InputError(file + ":" + std::to_string(e.mark.line + 1) +
                         ": malformed YAML: " + e.msg);
  }
}

std::string join(const std::string& where, const std::string& key) {
  return where.empty() ? key : where + "." + key;
}

YAML::Node node_at(const YAML::Node& map, const std::string& path) {
  YAML::Node at;
  at.reset(map);
  std::size_t from = 0;
  while (from <= path.size()) {
    const std::size_t dot = path.find('.', from);
    const std::string step = path.substr(from, dot == std::string::npos ? std::string::npos : dot - from);
    if (!at.IsMap() || !at[step]) break;
    const YAML::Node next = at[step];
    at.reset(next);
    if (dot == std::string::npos) break;
    from = dot + 1;
  }
  return at;
}

void Reader::fail(const YAML::Node& node, const std::string& key, const std::string& what) const {
  // "key = value: rule" reads as one phrase; anything else follows "key: ".
  const std::string sep = what.starts_with("= ") ? " " : ": ";
  // An overridden key (or one inside it) has no line in the file: name the override, the
  // last one that covers it (it set the value).
  for (auto it = overrides_.rbegin(); it != overrides_.rend(); ++it) {
    const Override& o = *it;
    if (key == o.key || key.starts_with(o.key + ".") || key.starts_with(o.key + "[")) {
      throw io::InputError(file_ + ": " + o.flag + " " + io::echo(o.key) + "=" + io::echo(o.value) +
                           ": " + io::echo(key) + sep + what);
    }
  }
  const int line = node.IsDefined() && node.Mark().line >= 0 ? node.Mark().line + 1 : 0;
  // The key path is the file's own text: echoed (escaped, bounded) like any input.
  throw io::InputError(file_ + ":" + std::to_string(line) + ": " + io::echo(key) + sep + what);
}

std::string Reader::key_text(const YAML::Node& key, const std::string& where) const {
  if (!key.IsScalar()) fail(key, where.empty() ? "(top level)" : where, "a key must be a plain name");
  return key.Scalar();
}

void Reader::only(const YAML::Node& map, const std::string& where,
                  const std::set<std::string>& keys) const {
  if (!map.IsMap()) fail(map, where.empty() ? "(top level)" : where, "expected a mapping");
  std::set<std::string> seen;
  for (const auto& kv : map) {
    const std::string k = key_text(kv.first, where);
    if (!keys.count(k)) fail(kv.first, join(where, k), "unknown key");
    // yaml-cpp keeps both and a lookup finds the first: the second would be ignored.
    if (!seen.insert(k).second) fail(kv.first, join(where, k), "given twice");
  }
}

double Reader::number(const YAML::Node& n, const std::string& key) const {
  if (!n.IsScalar()) fail(n, key, "expected a number");
  try {
    return n.as<double>();
  } catch (const YAML::Exception&) {
    fail(n, key, "expected a number");
  }
}

double Reader::integer(const YAML::Node& n, const std::string& key, double lo,
                       double hi_exclusive) const {
  const double v = number(n, key);
  if (!(v == std::floor(v))) fail(n, key, "expected a whole number");
  if (!(v >= lo && v < hi_exclusive))
    fail(n, key, "= " + format_shortest(v) + ": must be a whole number in [" + format_shortest(lo) +
                     ", " + format_shortest(hi_exclusive) + ")");
  return v;
}

std::string Reader::text(const YAML::Node& n, const std::string& key) const {
  if (!n.IsScalar()) fail(n, key, "expected a string");
  return n.Scalar();
}

bool Reader::boolean(const YAML::Node& n, const std::string& key) const {
  try {
    if (n.IsScalar()) return n.as<bool>();
  } catch (const YAML::Exception&) {
  }
  fail(n, key, "expected true or false");
}

void Reader::numbers(const YAML::Node& n, const std::string& key, double* out, int count) const {
  const std::string expected = "expected " + std::to_string(count) + " numbers";
  if (!n.IsSequence() || static_cast<int>(n.size()) != count) fail(n, key, expected);
  for (int i = 0; i < count; ++i) {
    if (!n[i].IsScalar()) fail(n, key, expected);
    try {
      out[i] = n[i].as<double>();
    } catch (const YAML::Exception&) {
      fail(n, key, expected);
    }
  }
}

Eigen::Vector3d Reader::vec3(const YAML::Node& n, const std::string& key) const {
  Eigen::Vector3d v;
  if (!n.IsSequence() || n.size() != 3) fail(n, key, "expected [x, y, z]");
  numbers(n, key, v.data(), 3);
  if (!v.allFinite()) fail(n, key, "must be finite");
  return v;
}

Eigen::Isometry3d Reader::transform(const YAML::Node& n, const std::string& key) const {
  double m[16];
  if (!n.IsSequence() || n.size() != 16) fail(n, key, "expected 16 numbers (4x4, row-major)");
  numbers(n, key, m, 16);
  Eigen::Matrix4d M;
  for (int i = 0; i < 16; ++i) M(i / 4, i % 4) = m[i];
  if (!M.row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1))) fail(n, key, "last row must be 0 0 0 1");
  Eigen::Isometry3d X;
  X.matrix() = M;
  return X;
}

void Out::list(const char* key, const double* v, std::size_t n) {
  std::ostream& os = line(key);
  os << "[";
  for (std::size_t i = 0; i < n; ++i) os << (i ? ", " : "") << format_shortest(v[i]);
  os << "]\n";
}

// Applies "a.b[0].c=value" to the tree; intermediate mappings are created, list elements
// must exist. The value is parsed as YAML.
Override apply_override(const std::string& file, YAML::Node& root, const std::string& text,
                        const std::string& flag) {
  const auto eq = text.find('=');
  if (eq == std::string::npos || eq == 0)
    throw io::InputError(file + ": " + flag + " " + text + ": expected key.path=value");
  Override o{text.substr(0, eq), text.substr(eq + 1), flag};
  auto bad = [&](const std::string& what) {
    throw io::InputError(file + ": " + flag + " " + text + ": " + what);
  };
  YAML::Node value;
  try {
    value = YAML::Load(o.value);
  } catch (const YAML::Exception& e) {
    bad("value is not valid YAML: " + e.msg);
  }
  if (!value.IsDefined() || value.IsNull()) bad("no value");
  // Split into steps: a key name or a list index.
  struct Step {
    std::string key;
    int index = -1;
  };
  std::vector<Step> steps;
  std::size_t i = 0;
  const std::string& k = o.key;
  while (i < k.size()) {
    if (k[i] == '.') {
      if (i == 0 || i + 1 == k.size() || k[i + 1] == '.') bad("empty key in '" + io::echo(k) + "'");
      ++i;
    } else if (k[i] == '[') {
      const auto close = k.find(']', i);
      if (close == std::string::npos || steps.empty()) bad("bad index in '" + io::echo(k) + "'");
      const std::string digits = k.substr(i + 1, close - i - 1);
      if (digits.empty() || digits.find_first_not_of("0123456789") != std::string::npos ||
          digits.size() > 6)
        bad("bad index '" + io::echo(digits) + "'");
      steps.push_back({"", std::stoi(digits)});
      i = close + 1;
    } else {
      const auto end = k.find_first_of(".[", i);
      steps.push_back({k.substr(i, end == std::string::npos ? std::string::npos : end - i)});
      i = end == std::string::npos ? k.size() : end;
    }
  }
  if (steps.empty() || steps.front().index >= 0) bad("no key");
  YAML::Node node;
  node.reset(root);
  for (std::size_t s = 0; s < steps.size(); ++s) {
    const bool last = s + 1 == steps.size();
    if (steps[s].index >= 0) {
      if (!node.IsSequence() || static_cast<int>(node.size()) <= steps[s].index)
        bad("the scene has no element " + std::to_string(steps[s].index) + " there");
      if (last) {
        node[steps[s].index] = value;
      } else {
        YAML::Node next = node[steps[s].index];
        node.reset(next);
      }
      continue;
    }
    if (!node.IsMap() && !node.IsNull()) bad("'" + steps[s].key + "' is inside a non-mapping");
    if (last) {
      node[steps[s].key] = value;
    } else {
      if (!node[steps[s].key]) node[steps[s].key] = YAML::Node(YAML::NodeType::Map);
      YAML::Node next = node[steps[s].key];
      node.reset(next);
    }
  }
  return o;
}


}  // namespace linksight::sim::yaml
