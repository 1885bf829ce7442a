// The reference back end: one pass over the points in order.
#include "kernels.hpp"
#include "linksight/tracker/backend.hpp"

namespace linksight {
namespace {

class SerialBackend final : public Backend {
 public:
  BackendKind kind() const override { return BackendKind::serial; }
  void set_points(const PointsView& points) override {
    points_ = points;
    assoc_.resize(points.size());  // grows only in capacity
  }
  void associate(const std::vector<float>& q, Accumulation& acc) override {
    const int m = static_cast<int>(q.size() / 3);
    acc.reset(m);
    detail::associate_range(points_.x.data(), points_.y.data(), points_.z.data(), 0, points_.size(),
                            q.data(), m, assoc_.data(), acc.sum.data(), acc.count.data());
  }
  std::span<const std::int32_t> association() override { return assoc_; }

 private:
  PointsView points_;
  std::vector<std::int32_t> assoc_;
};

}  // namespace

std::unique_ptr<Backend> make_serial_backend() { return std::make_unique<SerialBackend>(); }

}  // namespace linksight
