#include "linksight/tracker/backend.hpp"

#include <stdexcept>
#include <string>

namespace linksight {

std::unique_ptr<Backend> make_serial_backend();
std::unique_ptr<Backend> make_openmp_backend(int threads);

std::string_view to_string(BackendKind kind) {
  switch (kind) {
    case BackendKind::serial:
      return "serial";
    case BackendKind::openmp:
      return "openmp";
  }
  return "unknown";
}

BackendKind parse_backend(std::string_view name) {
  if (name == "serial") return BackendKind::serial;
  if (name == "openmp") return BackendKind::openmp;
  throw std::invalid_argument("unknown backend '" + std::string(name) +
                              "' (expected serial or openmp)");
}

void Accumulation::reset(int n_nodes) {
  sum.assign(3 * static_cast<std::size_t>(n_nodes), 0.0);
  count.assign(static_cast<std::size_t>(n_nodes), 0);
}

std::unique_ptr<Backend> make_backend(BackendKind kind, int threads) {
  if (threads < 0 || threads > 1024) {
    throw std::invalid_argument("threads = " + std::to_string(threads) + ": must be in [0, 1024]");
  }
  switch (kind) {
    case BackendKind::serial:
      return make_serial_backend();
    case BackendKind::openmp:
      return make_openmp_backend(threads);
  }
  throw std::invalid_argument("unknown backend kind");
}

}  // namespace linksight
