#pragma once
/// @file Back ends for the data-parallel part of one SOM iteration: association
/// (Eq. 11) and per-node accumulation for the mean (Eq. 12).

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "linksight/tracker/init.hpp"
#include "linksight/tracker/limits.hpp"

namespace linksight {

class ChainPassDevice;  // chain-fit's passes on a back end's device (tracker-internal)

enum class BackendKind { serial, openmp, opencl };

/// "serial" / "openmp" / "opencl"; parse throws std::invalid_argument naming the value.
[[nodiscard]] std::string_view to_string(BackendKind kind);
[[nodiscard]] BackendKind parse_backend(std::string_view name);

/// How the OpenCL back end sums points per node (kernel 2 of Algorithm 2). Both add
/// the same 64-bit fixed-point integers, so both give identical results.
enum class ClAccumulation {
  reduction,  ///< per-work-group partial sums in local memory, then an ordered sum
  atomic,     ///< the paper's global atomics (int64 fixed point: OpenCL 1.2 has no float atomics)
};

/// "reduction" / "atomic"; parse throws std::invalid_argument naming the value.
[[nodiscard]] std::string_view to_string(ClAccumulation accumulation);
[[nodiscard]] ClAccumulation parse_cl_accumulation(std::string_view name);

/// The largest OpenCLOptions::work_group_size validate() accepts; the device's own, often
/// lower, limit is checked when the back end is made.
inline constexpr std::size_t kMaxClWorkGroupSize = 4096;

/// Where and how the OpenCL back end runs.
struct OpenCLOptions {
  int platform = -1;   ///< platform index; -1: any
  std::string device;  ///< case-insensitive substring of the device name; "": first
  ClAccumulation accumulation = ClAccumulation::reduction;
  std::size_t work_group_size = 0;  ///< 0: min(256, what the device allows)
  void validate() const;            ///< throws std::invalid_argument naming the field
};

/// Thrown when a back end cannot run here (no OpenCL platform or device, a missing
/// extension). The message says what is missing and how to get it.
class BackendUnavailable : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Per-node sums are 64-bit fixed point with this many units per metre, in every back
/// end. Integer addition is exact and associative, so serial, OpenMP and OpenCL (any
/// thread count, work-group size or schedule) produce the same bits. Scaling a float by
/// a power of two is exact, so coordinates of 2^-9 m or more convert without rounding.
inline constexpr double kFixedPerMetre = 4294967296.0;  // 2^32
// kMaxCoordinate and kMaxPoints: limits.hpp.

/// Whether the tracker keeps a point of a cloud [m]: finite, and within kMaxCoordinate.
enum class PointCheck { kept, non_finite, out_of_range };
[[nodiscard]] inline PointCheck check_point(float x, float y, float z) {
  if (!(std::isfinite(x) && std::isfinite(y) && std::isfinite(z))) return PointCheck::non_finite;
  constexpr auto limit = static_cast<float>(kMaxCoordinate);
  if (std::abs(x) > limit || std::abs(y) > limit || std::abs(z) > limit)
    return PointCheck::out_of_range;
  return PointCheck::kept;
}

/// Per-node sums of one association pass.
struct Accumulation {
  std::vector<std::int64_t> sum;    ///< 3 per node: Σx, Σy, Σz in fixed point (kFixedPerMetre)
  std::vector<std::int64_t> count;  ///< |N_j|
  void reset(int n_nodes);
  /// Mean of node j's points [m] (Eq. 12); requires count[j] > 0.
  [[nodiscard]] Eigen::Vector3d mean(int j) const;
};

/// One implementation per file. The serial one is the reference; others must give the
/// same associations and sums equal to it within rounding (centres within 1e-6 m).
class Backend {
 public:
  virtual ~Backend() = default;
  [[nodiscard]] virtual BackendKind kind() const = 0;
  /// The frame's points: once per frame. The view must stay valid until the next call
  /// (CPU back ends read it in place; a device back end uploads it here, once).
  virtual void set_points(const PointsView& points) = 0;
  /// One pass: associates every point with its nearest node (ties: lowest index) and
  /// fills sums and counts. Nodes as float xyz.
  virtual void associate(const std::vector<float>& nodes_xyz, Accumulation& acc) = 0;
  /// Associations of the last pass, one per point (a device back end reads them back
  /// only when asked).
  [[nodiscard]] virtual std::span<const std::int32_t> association() = 0;
  /// Device time of the kernels since set_points [s]; 0 for CPU back ends.
  [[nodiscard]] virtual double device_seconds() const { return 0.0; }
  /// Where chain-fit's passes run on this back end's device (OpenCL); nullptr: the fit
  /// runs them on the host (serial, OpenMP, or a device without double precision).
  [[nodiscard]] virtual ChainPassDevice* chain_pass_device() { return nullptr; }
};

/// `threads` is used by OpenMP only (0: one per core); `opencl` by the OpenCL back end.
/// Throws BackendUnavailable when the back end cannot run on this machine.
[[nodiscard]] std::unique_ptr<Backend> make_backend(BackendKind kind, int threads,
                                                    const OpenCLOptions& opencl = {});

}  // namespace linksight
