// The OpenCL back end of a build without OpenCL (no headers or ICD loader at configure
// time): it reports itself unavailable, as on a machine with no OpenCL platform.
#include <string>

#include "linksight/tracker/backend.hpp"
#include "linksight/tracker/opencl.hpp"

namespace linksight {
namespace {

[[noreturn]] void unavailable() {
  throw BackendUnavailable(std::string(kNoOpenCLPlatform) + "; " + kNoOpenCLBuild);
}

}  // namespace

std::unique_ptr<Backend> make_opencl_backend(const OpenCLOptions& options) {
  options.validate();
  unavailable();
}

bool opencl_built() { return false; }

std::vector<OpenCLDevice> opencl_devices() { return {}; }

BackendKind auto_backend() { return BackendKind::openmp; }

void check_opencl_build(const std::string& /*source*/, const OpenCLOptions& /*options*/) {
  unavailable();
}

}  // namespace linksight
