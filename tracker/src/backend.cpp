#include "linksight/tracker/backend.hpp"

#include <stdexcept>
#include <string>

namespace linksight {

std::unique_ptr<Backend> make_serial_backend();
std::unique_ptr<Backend> make_openmp_backend(int threads);
std::unique_ptr<Backend> make_opencl_backend(const OpenCLOptions& options);

std::string_view to_string(BackendKind kind) {
  switch (kind) {
    case BackendKind::serial:
      return "serial";
    case BackendKind::openmp:
      return "openmp";
    case BackendKind::opencl:
      return "opencl";
  }
  return "unknown";
}

BackendKind parse_backend(std::string_view name) {
  if (name == "serial") return BackendKind::serial;
  if (name == "openmp") return BackendKind::openmp;
  if (name == "opencl") return BackendKind::opencl;
  throw std::invalid_argument("unknown backend '" + std::string(name) +
                              "' (expected serial, openmp or opencl)");
}

void Accumulation::reset(int n_nodes) {
  sum.assign(3 * static_cast<std::size_t>(n_nodes), 0);
  count.assign(static_cast<std::size_t>(n_nodes), 0);
}

Eigen::Vector3d Accumulation::mean(int j) const {
  const std::size_t k = static_cast<std::size_t>(j);
  // Sums stay below 2^53 within kMaxCoordinate and kMaxPoints, so the conversion is exact.
  const double scale = kFixedPerMetre * static_cast<double>(count[k]);
  return {static_cast<double>(sum[3 * k]) / scale, static_cast<double>(sum[3 * k + 1]) / scale,
          static_cast<double>(sum[3 * k + 2]) / scale};
}

std::string_view to_string(ClAccumulation accumulation) {
  return accumulation == ClAccumulation::atomic ? "atomic" : "reduction";
}

ClAccumulation parse_cl_accumulation(std::string_view name) {
  if (name == "reduction") return ClAccumulation::reduction;
  if (name == "atomic") return ClAccumulation::atomic;
  throw std::invalid_argument("unknown accumulation '" + std::string(name) +
                              "' (expected reduction or atomic)");
}

void OpenCLOptions::validate() const {
  if (platform < -1) {
    throw std::invalid_argument("OpenCLOptions.platform = " + std::to_string(platform) +
                                ": must be >= 0, or -1 for any");
  }
  if (work_group_size > kMaxClWorkGroupSize) {
    throw std::invalid_argument(
        "OpenCLOptions.work_group_size = " + std::to_string(work_group_size) +
        ": must be <= " + std::to_string(kMaxClWorkGroupSize) + " (0: auto)");
  }
}

std::unique_ptr<Backend> make_backend(BackendKind kind, int threads, const OpenCLOptions& opencl) {
  if (threads < 0 || threads > 1024) {
    throw std::invalid_argument("threads = " + std::to_string(threads) + ": must be in [0, 1024]");
  }
  switch (kind) {
    case BackendKind::serial:
      return make_serial_backend();
    case BackendKind::openmp:
      return make_openmp_backend(threads);
    case BackendKind::opencl:
      return make_opencl_backend(opencl);
  }
  throw std::invalid_argument("unknown backend kind");
}

}  // namespace linksight
