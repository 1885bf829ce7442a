#include "linksight/io/csv.hpp"

#include <fstream>
#include <sstream>
#include <system_error>

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

bool read_bounded_line(std::istream& in, std::string& line, std::size_t max_bytes, bool& too_long) {
  line.clear();
  too_long = false;
  std::streambuf* buf = in.rdbuf();
  bool any = false;
  for (;;) {
    const auto c = buf->sbumpc();
    if (c == std::char_traits<char>::eof()) {
      in.setstate(std::ios::eofbit);
      return any;
    }
    any = true;
    if (c == '\n') return true;
    if (line.size() + 1 >= max_bytes) {
      too_long = true;
      return true;
    }
    line.push_back(static_cast<char>(c));
  }
}

CsvTable read_csv(const std::filesystem::path& path, const CsvLimits& limits) {
  namespace fs = std::filesystem;
  const std::string file = path.string();
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (!fs::exists(st)) throw InputError(file + ": cannot be read (no such file)");
  // A folder, device or FIFO is refused before a byte is read: /dev/zero never ends, and
  // a FIFO waits for a writer.
  if (!fs::is_regular_file(st))
    throw InputError(file + (fs::is_directory(st) ? ": a folder, not a CSV file"
                                                  : ": not a regular file (a device or FIFO?)"));
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(file + ": cannot be read");
  CsvTable t;
  std::string line;
  int n = 0;
  const auto next = [&] {
    bool too_long = false;
    if (!read_bounded_line(in, line, limits.max_line_bytes, too_long)) return false;
    ++n;
    if (too_long)
      throw InputError(file + ":" + std::to_string(n) + ": a line of " +
                       std::to_string(limits.max_line_bytes) + " bytes or more (a row of this " +
                       "table is short)");
    if (!line.empty() && line.back() == '\r') line.pop_back();
    return true;
  };
  if (!next()) throw InputError(file + ": empty file");
  t.header = split(line, ',');
  if (t.header.size() > limits.max_columns)
    throw InputError(file + ":1: " + std::to_string(t.header.size()) + " columns, more than " +
                     std::to_string(limits.max_columns) + " (this table has fewer)");
  while (next()) {
    if (line.empty()) continue;
    if (t.rows.size() == limits.max_rows)
      throw InputError(file + ":" + std::to_string(n) + ": more than " +
                       std::to_string(limits.max_rows) + " rows (what this file can hold)");
    t.rows.push_back(split(line, ','));
    t.lines.push_back(n);
    if (t.rows.back().size() != t.header.size())
      throw InputError(file + ":" + std::to_string(n) + ": " +
                       std::to_string(t.rows.back().size()) + " fields, expected " +
                       std::to_string(t.header.size()));
  }
  return t;
}

}  // namespace linksight::io
