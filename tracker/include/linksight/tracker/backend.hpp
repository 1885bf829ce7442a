#pragma once
/// @file Back ends for the data-parallel part of one SOM iteration: association
/// (Eq. 11) and per-node accumulation for the mean (Eq. 12).

#include <cstdint>
#include <memory>
#include <string_view>
#include <vector>

#include "linksight/tracker/init.hpp"

namespace linksight {

enum class BackendKind { serial, openmp };

/// "serial" / "openmp"; parse throws std::invalid_argument naming the value.
[[nodiscard]] std::string_view to_string(BackendKind kind);
[[nodiscard]] BackendKind parse_backend(std::string_view name);

/// Per-node sums of one association pass.
struct Accumulation {
  std::vector<double> sum;          ///< 3 per node: Σx, Σy, Σz [m]
  std::vector<std::int64_t> count;  ///< |N_j|
  void reset(int n_nodes);
};

/// One implementation per file. The serial one is the reference; others must give the
/// same associations and sums equal to it within rounding (centres within 1e-6 m).
class Backend {
 public:
  virtual ~Backend() = default;
  [[nodiscard]] virtual BackendKind kind() const = 0;
  /// Associates every point with its nearest node (ties: lowest index), writes
  /// `association[i]`, and accumulates sums and counts. Nodes are given as float xyz.
  virtual void associate(const PointsView& points, const std::vector<float>& nodes_xyz,
                         std::int32_t* association, Accumulation& acc) = 0;
};

/// `threads` is used by parallel back ends only; 0 means one per available core.
[[nodiscard]] std::unique_ptr<Backend> make_backend(BackendKind kind, int threads);

}  // namespace linksight
