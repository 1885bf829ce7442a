#pragma once
/// @file Comma-separated tables as the project writes them: a header line, then rows of
/// plain fields (no quoting). One reader for every CSV input (sweep shards, base poses).

#include <filesystem>
#include <string>
#include <vector>

namespace linksight::io {

/// `s` split at every `sep`; a trailing separator gives a last empty field.
[[nodiscard]] std::vector<std::string> split(const std::string& s, char sep);

struct CsvTable {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;  ///< each with header.size() fields
  std::vector<int> lines;                      ///< each row's line in the file (1-based)
};

/// Reads a table; blank lines are skipped and a CR before a line end dropped. Throws
/// InputError "<file>: cannot be read", "<file>: empty file" or "<file>:<line>: N fields,
/// expected M".
[[nodiscard]] CsvTable read_csv(const std::filesystem::path& path);

}  // namespace linksight::io
