#include "linksight/io/csv.hpp"

#include <fstream>
#include <sstream>

#include "linksight/io/error.hpp"

namespace linksight::io {

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::string item;
  std::stringstream ss(s);
  while (std::getline(ss, item, sep)) out.push_back(item);
  if (!s.empty() && s.back() == sep) out.emplace_back();
  return out;
}

CsvTable read_csv(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path.string() + ": cannot be read");
  CsvTable t;
  std::string line;
  const auto next = [&] {
    if (!std::getline(in, line)) return false;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    return true;
  };
  if (!next()) throw InputError(path.string() + ": empty file");
  t.header = split(line, ',');
  int n = 1;
  while (next()) {
    ++n;
    if (line.empty()) continue;
    t.rows.push_back(split(line, ','));
    t.lines.push_back(n);
    if (t.rows.back().size() != t.header.size())
      throw InputError(path.string() + ":" + std::to_string(n) + ": " +
                       std::to_string(t.rows.back().size()) + " fields, expected " +
                       std::to_string(t.header.size()));
  }
  return t;
}

}  // namespace linksight::io
