#pragma once
/// @file OpenCL devices: what is installed, and which back end `auto` picks.

#include <cstdint>
#include <string>
#include <vector>

#include "linksight/tracker/backend.hpp"

namespace linksight {

/// One OpenCL device as the ICD loader reports it.
struct OpenCLDevice {
  int platform_index = 0, device_index = 0;
  std::string platform, name, version, type;  ///< type: GPU, CPU, ACCELERATOR or OTHER
  unsigned compute_units = 0;
  std::uint64_t global_memory_bytes = 0, local_memory_bytes = 0;
  std::size_t max_work_group_size = 0;
  bool int64_atomics = false;  ///< cl_khr_int64_base_atomics: needed by the back end
  bool fp64 = false;           ///< cl_khr_fp64: chain-fit's kernels need it
  /// CL_FP_CORRECTLY_ROUNDED_DIVIDE_SQRT in CL_DEVICE_SINGLE_FP_CONFIG: chain-fit's kernels
  /// need it too (their float search must round as the CPU's); without either, its passes
  /// run on the host.
  bool fp32_rounded_sqrt = false;
};

/// Whether this build has the OpenCL back end (OpenCL headers and an ICD loader were
/// found at configure time). Without it, the back end throws BackendUnavailable.
[[nodiscard]] bool opencl_built();

/// The message of the BackendUnavailable thrown where no OpenCL platform exists.
inline constexpr const char* kNoOpenCLPlatform =
    "OpenCL back end: no OpenCL platform found. Install an OpenCL driver (ICD): on "
    "Debian 'apt-get install pocl-opencl-icd' gives a CPU device; a GPU needs its "
    "vendor's ICD";

/// What a build without OpenCL says (the back end's error, `linksight devices`, skipped tests).
inline constexpr const char* kNoOpenCLBuild =
    "this build has no OpenCL back end: OpenCL headers and an ICD loader were not found at "
    "configure time (apt-get install ocl-icd-opencl-dev opencl-headers, then configure "
    "again)";

/// Every device of every platform; empty when no OpenCL platform is installed.
[[nodiscard]] std::vector<OpenCLDevice> opencl_devices();

/// `opencl` when a GPU device with the needed extensions exists, else `openmp`.
[[nodiscard]] BackendKind auto_backend();

/// Compiles OpenCL C `source` for the device `options` select; throws std::runtime_error
/// with the compiler's build log on failure (diagnostics for kernel changes).
void check_opencl_build(const std::string& source, const OpenCLOptions& options = {});

}  // namespace linksight
