#pragma once
/// @file A tracker's estimates (or the truth) as a table of nodes per frame: what
/// `linksight score` reads. Columns `frame,node,x_m,y_m,z_m` (camera frame [m]) in any
/// order, other columns ignored (run's nodes.csv, render's truth.csv and a tracker's own
/// file all read), rows in any order.

#include <cstddef>
#include <filesystem>
#include <optional>
#include <vector>

#include "linksight/tracker/model.hpp"

namespace linksight::io {

/// Per frame 0..frames-1 its nodes, or none when the file has no row for that frame.
/// `frames` / `nodes` 0: as many as the file names (its largest index + 1). Throws
/// InputError "<file>:<line>: <problem>" for: a required column missing or given twice; a
/// frame or node that is not an index, or not below `frames` / `nodes` ("not among the
/// truth's"); a (frame, node) given twice; a coordinate that is not a finite number; a
/// frame with some of its nodes but not all (the line of its first row); more rows than
/// the table can hold, checked while reading: rows_with_room of `max_rows` when given,
/// else of frames x nodes when both are given, and never more than kMaxCsvRows
/// (limits.hpp); and read_csv's refusals.
[[nodiscard]] std::vector<std::optional<Nodes>> read_nodes_csv(const std::filesystem::path& path,
                                                               std::size_t frames = 0,
                                                               std::size_t nodes = 0,
                                                               std::size_t max_rows = 0);

}  // namespace linksight::io
