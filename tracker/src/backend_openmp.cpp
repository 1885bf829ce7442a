// OpenMP back end. Points are cut into fixed-size chunks whatever the thread count, and
// sums are fixed-point integers, so the result is bit-identical to serial for any number
// of threads.

#include <omp.h>

#include <algorithm>

#include "kernels.hpp"
#include "linksight/tracker/backend.hpp"

namespace linksight {
namespace {

constexpr std::size_t kChunk = 16 * detail::kBlock;

class OpenMPBackend final : public Backend {
 public:
  explicit OpenMPBackend(int threads) : threads_(threads > 0 ? threads : omp_get_num_procs()) {}
  BackendKind kind() const override { return BackendKind::openmp; }

  void set_points(const PointsView& points) override {
    points_ = points;
    assoc_.resize(points.size());
  }
  std::span<const std::int32_t> association() override { return assoc_; }

  void associate(const std::vector<float>& q, Accumulation& acc) override {
    const PointsView& p = points_;
    std::int32_t* assoc = assoc_.data();
    const int m = static_cast<int>(q.size() / 3);
    const std::size_t n = p.size();
    const std::size_t chunks = (n + kChunk - 1) / kChunk;
    // Buffers only grow: a steady frame size allocates nothing.
    if (sum_.size() < chunks * 3 * m) sum_.resize(chunks * 3 * m);
    if (count_.size() < chunks * m) count_.resize(chunks * m);
    const float *x = p.x.data(), *y = p.y.data(), *z = p.z.data();
    const long long nc = static_cast<long long>(chunks);
#pragma omp parallel for num_threads(threads_) schedule(static)
    for (long long c = 0; c < nc; ++c) {
      const std::size_t cu = static_cast<std::size_t>(c);
      std::int64_t* s = sum_.data() + cu * 3 * m;
      std::int64_t* k = count_.data() + cu * m;
      std::fill(s, s + 3 * m, std::int64_t{0});
      std::fill(k, k + m, 0);
      const std::size_t begin = cu * kChunk;
      const std::size_t end = std::min(n, begin + kChunk);
      detail::associate_range(x, y, z, begin, end, q.data(), m, assoc, s, k);
    }
    acc.reset(m);
    for (std::size_t c = 0; c < chunks; ++c) {
      for (int j = 0; j < 3 * m; ++j) acc.sum[j] += sum_[c * 3 * m + j];
      for (int j = 0; j < m; ++j) acc.count[j] += count_[c * m + j];
    }
  }

 private:
  int threads_;
  PointsView points_;
  std::vector<std::int32_t> assoc_;
  std::vector<std::int64_t> sum_;
  std::vector<std::int64_t> count_;
};

}  // namespace

std::unique_ptr<Backend> make_openmp_backend(int threads) {
  return std::make_unique<OpenMPBackend>(threads);
}

}  // namespace linksight
