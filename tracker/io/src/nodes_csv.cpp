#include "linksight/io/nodes_csv.hpp"
#include "linksight/tracker/limits.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <string>

#include "linksight/io/csv.hpp"
#include "linksight/io/error.hpp"
#include "linksight/tracker/backend.hpp"
#include "linksight/tracker/format.hpp"

namespace linksight::io {
namespace {

constexpr std::array<const char*, 5> kColumns = {"frame", "node", "x_m", "y_m", "z_m"};
// The table's allocation is not the file's choice: kMaxCsvFrame and kMaxCsvNode
// (limits.hpp) bound the indices.
constexpr std::size_t kMaxIndex = kMaxCsvFrame;
constexpr std::size_t kMaxNode = kMaxCsvNode;

std::size_t index_of(const std::string& s, const std::string& where, const char* what) {
  std::size_t v = 0;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  if (r.ec != std::errc() || r.ptr != s.data() + s.size() || v > kMaxIndex)
    throw InputError(where + what + " '" + echo(s) + "' is not an index");
  return v;
}

}  // namespace

std::vector<std::optional<Nodes>> read_nodes_csv(const std::filesystem::path& path,
                                                 std::size_t frames, std::size_t nodes,
                                                 std::size_t max_rows) {
  const std::string file = path.string();
  // Each (frame, node) once at most, so a table of known size holds frames x nodes rows;
  // kMaxCsvRows caps it whatever a recording's own files claim.
  CsvLimits limits;
  limits.max_rows = std::min(max_rows != 0               ? rows_with_room(max_rows)
                             : frames != 0 && nodes != 0 ? rows_with_room(frames * nodes)
                                                         : kMaxCsvRows,
                             kMaxCsvRows);
  const CsvTable t = read_csv(path, limits);
  std::array<std::size_t, kColumns.size()> at{};
  std::array<bool, kColumns.size()> found{};
  for (std::size_t h = 0; h < t.header.size(); ++h)
    for (std::size_t c = 0; c < kColumns.size(); ++c) {
      if (t.header[h] != kColumns[c]) continue;
      if (found[c]) throw InputError(file + ":1: column '" + echo(t.header[h]) + "' given twice");
      found[c] = true;
      at[c] = h;
    }
  for (std::size_t c = 0; c < kColumns.size(); ++c)
    if (!found[c])
      throw InputError(file + ":1: no column '" + kColumns[c] +
                       "' (expected frame,node,x_m,y_m,z_m)");

  // Indices first, so that the sizes are known (or checked) before any allocation.
  std::vector<std::size_t> frame_of(t.rows.size()), node_of(t.rows.size());
  std::size_t n_frames = frames, n_nodes = nodes;
  for (std::size_t r = 0; r < t.rows.size(); ++r) {
    const std::string where = file + ":" + std::to_string(t.lines[r]) + ": ";
    frame_of[r] = index_of(t.rows[r][at[0]], where, "frame");
    node_of[r] = index_of(t.rows[r][at[1]], where, "node");
    if (node_of[r] > kMaxNode)
      throw InputError(where + "node " + std::to_string(node_of[r]) + " is more than " +
                       std::to_string(kMaxNode) + " (not a node of a chain)");
    if (frames != 0 && frame_of[r] >= frames)
      throw InputError(where + "frame " + std::to_string(frame_of[r]) +
                       " is not among the truth's " + std::to_string(frames) + " frames");
    if (nodes != 0 && node_of[r] >= nodes)
      throw InputError(where + "node " + std::to_string(node_of[r]) +
                       " is not among the truth's " + std::to_string(nodes) +
                       " nodes per frame (0.." + std::to_string(nodes - 1) + ")");
    if (frames == 0) n_frames = std::max(n_frames, frame_of[r] + 1);
    if (nodes == 0) n_nodes = std::max(n_nodes, node_of[r] + 1);
  }

  // Rows per frame before any frame's nodes are allocated: a frame with fewer rows than
  // nodes is refused here, so the table is never larger than the file's rows.
  std::vector<std::size_t> rows_of(n_frames, 0);
  std::vector<int> first_row(n_frames, 0);
  for (std::size_t r = 0; r < t.rows.size(); ++r)
    if (rows_of[frame_of[r]]++ == 0) first_row[frame_of[r]] = t.lines[r];
  for (std::size_t f = 0; f < n_frames; ++f)
    if (rows_of[f] != 0 && rows_of[f] < n_nodes)
      throw InputError(file + ":" + std::to_string(first_row[f]) + ": frame " +
                       std::to_string(f) + " has " + std::to_string(rows_of[f]) + " of the " +
                       std::to_string(n_nodes) + " nodes");

  std::vector<std::optional<Nodes>> out(n_frames);
  std::vector<std::vector<int>> line_of(n_frames);
  std::vector<std::size_t> given(n_frames, 0);
  std::vector<int> first_line(n_frames, 0);
  for (std::size_t r = 0; r < t.rows.size(); ++r) {
    const std::vector<std::string>& row = t.rows[r];
    const std::string where = file + ":" + std::to_string(t.lines[r]) + ": ";
    const std::size_t f = frame_of[r], j = node_of[r];
    if (!out[f]) {
      out[f] = Nodes(n_nodes, Eigen::Vector3d::Zero());
      line_of[f].assign(n_nodes, 0);
      first_line[f] = t.lines[r];
    }
    if (line_of[f][j] != 0)
      throw InputError(where + "frame " + std::to_string(f) + " node " + std::to_string(j) +
                       " given twice (first on line " + std::to_string(line_of[f][j]) + ")");
    line_of[f][j] = t.lines[r];
    ++given[f];
    for (std::size_t c = 2; c < kColumns.size(); ++c) {
      const std::string& s = row[at[c]];
      double x = 0;
      const auto rv = std::from_chars(s.data(), s.data() + s.size(), x);
      if (rv.ec != std::errc() || rv.ptr != s.data() + s.size() || !std::isfinite(x))
        throw InputError(where + kColumns[c] + " '" + echo(s) + "' is not a finite number");
      if (std::abs(x) > kMaxCoordinate)
        throw InputError(where + kColumns[c] + " '" + echo(s) + "' is beyond " +
                         format_shortest(kMaxCoordinate) + " m (a tracker's limit)");
      (*out[f])[j][static_cast<Eigen::Index>(c - 2)] = x;
    }
  }
  for (std::size_t f = 0; f < n_frames; ++f)
    if (out[f] && given[f] != n_nodes)
      throw InputError(file + ":" + std::to_string(first_line[f]) + ": frame " +
                       std::to_string(f) + " has " + std::to_string(given[f]) + " of the " +
                       std::to_string(n_nodes) + " nodes");
  return out;
}

}  // namespace linksight::io
