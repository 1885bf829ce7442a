#pragma once
/// @file Untrusted JSON (tracker answers, sweep.json, a recording's camera.json and
/// chain.json, intrinsics.json): its depth bounded before a parser or a dump can recurse,
/// and its values summarized, never dumped whole, when a message shows one.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

#include "linksight/io/echo.hpp"

namespace linksight::io {

/// The deepest nesting of arrays and objects an input document may have. The project's
/// own documents nest 3 deep; nlohmann/json's dump and comparison recurse once a level.
inline constexpr std::size_t kMaxJsonDepth = 64;

/// The byte offset at which `text` opens its (kMaxJsonDepth + 1)-th level of nesting, or
/// std::string_view::npos when it nests no deeper. Brackets inside strings do not count;
/// the text need not be valid JSON.
[[nodiscard]] std::size_t json_too_deep_at(std::string_view text);

/// Throws InputError "<source>: JSON nested deeper than 64 levels (byte N)" when `text`
/// nests deeper than kMaxJsonDepth.
void check_json_depth(std::string_view text, const std::string& source);

/// The largest JSON file linksight reads [bytes]: its own are under 10 KB (a sweep's
/// manifest of 10,000 axis values about 200 KB).
inline constexpr std::uintmax_t kMaxJsonFileBytes = std::uintmax_t{1} << 24;

/// The text of the JSON file `path`, checked before any parser sees it: a regular file
/// (not a device, FIFO or folder), at most kMaxJsonFileBytes, nested at most
/// kMaxJsonDepth. Throws InputError "<file>: <if_missing>" when it does not exist,
/// otherwise naming the file and the check it fails.
[[nodiscard]] std::string read_json_file(const std::filesystem::path& path,
                                         const std::string& if_missing);

/// A JSON value for a message: a scalar as echo() of its JSON text; an array or object as
/// its type, size and the first few scalar members or keys, never a dump of a nested
/// value. Generic so that this header needs no JSON library (`Json` is nlohmann::json).
template <class Json>
[[nodiscard]] std::string json_summary(const Json& v) {
  constexpr std::size_t kShown = 3;
  if (v.is_array()) {
    std::string s = "an array of " + std::to_string(v.size());
    std::string items;
    std::size_t k = 0;
    for (const auto& e : v) {
      if (k == kShown) break;
      if (e.is_array() || e.is_object()) return s + (k ? " [" + items + ", ...]" : "");
      items += k++ ? ", " : "";
      items += echo(e.dump(), kMaxEcho / kShown);
    }
    return v.empty() ? s : s + " [" + items + (v.size() > kShown ? ", ...]" : "]");
  }
  if (v.is_object()) {
    std::string s = "an object of " + std::to_string(v.size()) + " keys";
    std::string keys;
    std::size_t k = 0;
    for (auto it = v.begin(); it != v.end() && k < kShown; ++it) {
      keys += k++ ? ", \"" : "\"";
      keys += echo(it.key(), kMaxEcho / kShown);
      keys += '"';
    }
    return v.empty() ? s : s + " {" + keys + (v.size() > kShown ? ", ...}" : "}");
  }
  return echo(v.dump());
}

}  // namespace linksight::io
