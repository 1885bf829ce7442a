#include "linksight/io/json_input.hpp"

#include <fstream>
#include <iterator>
#include <system_error>

#include "linksight/io/error.hpp"

namespace linksight::io {

std::size_t json_too_deep_at(std::string_view text) {
  std::size_t depth = 0;
  bool in_string = false, escaped = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (escaped)
        escaped = false;
      else if (c == '\\')
        escaped = true;
      else if (c == '"')
        in_string = false;
      continue;
    }
    if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > kMaxJsonDepth) return i;
    } else if ((c == ']' || c == '}') && depth > 0) {
      --depth;
    }
  }
  return std::string_view::npos;
}

void check_json_depth(std::string_view text, const std::string& source) {
  const std::size_t at = json_too_deep_at(text);
  if (at != std::string_view::npos)
    throw InputError(source + ": JSON nested deeper than " + std::to_string(kMaxJsonDepth) +
                     " levels (byte " + std::to_string(at) + ")");
}

std::string read_json_file(const std::filesystem::path& path, const std::string& if_missing) {
  namespace fs = std::filesystem;
  const std::string file = path.string();
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (!fs::exists(st)) throw InputError(file + ": " + if_missing);
  if (!fs::is_regular_file(st)) throw InputError(file + ": not a regular file");
  const std::uintmax_t size = fs::file_size(path, ec);
  if (ec) throw InputError(file + ": cannot be read");
  if (size > kMaxJsonFileBytes)
    throw InputError(file + ": " + std::to_string(size) +
                     " bytes, more than a JSON input may have (" +
                     std::to_string(kMaxJsonFileBytes) + ")");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(file + ": cannot be read");
  std::string text;
  text.reserve(static_cast<std::size_t>(size));
  // Bounded again while reading: the file may have grown since its size was taken.
  char buf[1 << 16];
  while (in.read(buf, sizeof buf) || in.gcount() > 0) {
    text.append(buf, static_cast<std::size_t>(in.gcount()));
    if (text.size() > kMaxJsonFileBytes)
      throw InputError(file + ": more bytes than a JSON input may have (" +
                       std::to_string(kMaxJsonFileBytes) + ")");
  }
  check_json_depth(text, file);
  return text;
}

}  // namespace linksight::io
