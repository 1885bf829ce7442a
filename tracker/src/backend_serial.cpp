// The reference back end: one pass over the points in order.
#include "kernels.hpp"
#include "linksight/tracker/backend.hpp"

namespace linksight {
namespace {

class SerialBackend final : public Backend {
 public:
  BackendKind kind() const override { return BackendKind::serial; }
  void associate(const PointsView& p, const std::vector<float>& q, std::int32_t* assoc,
                 Accumulation& acc) override {
    const int m = static_cast<int>(q.size() / 3);
    acc.reset(m);
    detail::associate_range(p.x.data(), p.y.data(), p.z.data(), 0, p.size(), q.data(), m, assoc,
                            acc.sum.data(), acc.count.data());
  }
};

}  // namespace

std::unique_ptr<Backend> make_serial_backend() { return std::make_unique<SerialBackend>(); }

}  // namespace linksight
