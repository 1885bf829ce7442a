// linksight devices: what OpenCL sees on this machine.
#include <iostream>

#include "commands.hpp"
#include "linksight/tracker/opencl.hpp"

namespace linksight::cli {
namespace {

int run_devices() {
  if (!opencl_built()) {
    std::cout << kNoOpenCLBuild << ".\n";
    return kExitOk;
  }
  const auto devices = opencl_devices();
  if (devices.empty()) {
    std::cout
        << "no OpenCL platform found. Install an OpenCL driver (ICD): on Debian "
           "'apt-get install pocl-opencl-icd' gives a CPU device; a GPU needs its vendor's ICD.\n";
    return kExitOk;
  }
  int last_platform = -1;
  for (const OpenCLDevice& d : devices) {
    if (d.platform_index != last_platform) {
      std::cout << "platform " << d.platform_index << ": " << d.platform << "\n";
      last_platform = d.platform_index;
    }
    std::cout << "  device " << d.device_index << ": " << d.name << " [" << d.type << "]\n"
              << "    version:        " << d.version << "\n"
              << "    compute units:  " << d.compute_units << "\n"
              << "    global memory:  " << d.global_memory_bytes / (1024 * 1024) << " MiB\n"
              << "    local memory:   " << d.local_memory_bytes / 1024 << " KiB\n"
              << "    max work group: " << d.max_work_group_size << "\n"
              << "    cl_khr_int64_base_atomics: "
              << (d.int64_atomics ? "yes" : "NO (opencl back end unusable)") << "\n"
              << "    cl_khr_fp64:    " << (d.fp64 ? "yes" : "no")
              << " (with the next: chain-fit's passes on the device, else on the host)\n"
              << "    correctly rounded float sqrt: " << (d.fp32_rounded_sqrt ? "yes" : "no")
              << "\n";
  }
  std::cout << "--backend auto picks: " << to_string(auto_backend()) << "\n";
  return kExitOk;
}

}  // namespace

Runner add_devices(CLI::App&) {
  return [] { return run_devices(); };
}

}  // namespace linksight::cli
