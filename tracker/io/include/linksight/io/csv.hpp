#pragma once
/// @file Comma-separated tables as the project writes them: a header line, then rows of
/// plain fields (no quoting). One reader for every CSV input (sweep shards, base poses,
/// nodes, a recording's tables), bounded by what the file can legitimately hold.

#include <cstddef>
#include <filesystem>
#include <istream>
#include <string>
#include <vector>

namespace linksight::io {

/// `s` split at every `sep`; a trailing separator gives a last empty field.
[[nodiscard]] std::vector<std::string> split(const std::string& s, char sep);

/// Reads the next line of `in` into `line` (without its '\n'), holding at most
/// `max_bytes` of it: true for a line, false at the end of the input; a line of
/// `max_bytes` bytes or more sets `too_long` and returns true with `line` cut. One reader
/// of bounded lines for the text formats (CSV, PLY).
bool read_bounded_line(std::istream& in, std::string& line, std::size_t max_bytes, bool& too_long);

/// What a CSV input may hold, each checked while it is read. Each caller derives
/// `max_rows` from what its file can legitimately hold (a truth's frames x nodes, a
/// shard's cells x modes): a file with more is not that file.
struct CsvLimits {
  std::size_t max_rows = 0;                           ///< data rows, blank lines not counted
  std::size_t max_columns = 64;                       ///< fields in the header
  std::size_t max_line_bytes = std::size_t{1} << 16;  ///< bytes in a line, '\n' excluded
};

/// The row limit for a table that legitimately holds `rows`: as many again, and 64 more.
/// A file with some rows too many is then refused by its reader's own checks, which say
/// what is wrong with them (a row given twice, a frame the truth does not have), not only
/// by their count; what it holds stays within about twice what the file may.
[[nodiscard]] constexpr std::size_t rows_with_room(std::size_t rows) { return 2 * rows + 64; }

struct CsvTable {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;  ///< each with header.size() fields
  std::vector<int> lines;                      ///< each row's line in the file (1-based)
};

/// Reads a table; blank lines are skipped and a CR before a line end dropped. Throws
/// InputError naming the file: "not a regular file" (a folder, device or FIFO, refused
/// before reading), "cannot be read", "empty file", "<line>: N fields, expected M", or a
/// limit passed ("<line>: a line of N bytes or more", "1: N columns, more than M",
/// "<line>: more than N rows (...)").
[[nodiscard]] CsvTable read_csv(const std::filesystem::path& path, const CsvLimits& limits);

}  // namespace linksight::io
