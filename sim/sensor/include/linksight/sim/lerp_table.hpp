#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <stdexcept>
#include <vector>

namespace linksight::sim {

/// A function tabulated at equal steps over [lo, hi] and read back by linear interpolation,
/// its argument held to [lo, hi]: what the sensor reads at every pixel instead of std::pow
/// (which cost a quarter of the frame there; bench/README.md). A NaN argument reads NaN.
class LerpTable {
 public:
  LerpTable() = default;
  /// f at lo + i (hi - lo) / steps for i = 0 .. steps + 1: one past the end, so that hi
  /// itself interpolates (f must accept that argument). Throws std::invalid_argument unless
  /// hi > lo, steps >= 1 and the step is a normal number.
  template <class F>
  LerpTable(double lo, double hi, std::size_t steps, F f) : lo_(lo), hi_(hi) {
    const double step = (hi - lo) / static_cast<double>(steps);
    if (!(hi > lo) || steps < 1 || !std::isnormal(step) || !std::isfinite(1 / step))
      throw std::invalid_argument("LerpTable: needs hi > lo, steps >= 1 and a normal step");
    per_ = 1 / step;
    values_.resize(steps + 2);
    for (std::size_t i = 0; i < values_.size(); ++i)
      values_[i] = f(lo + static_cast<double>(i) * step);
  }
  /// Whether it holds a function (a default-constructed table does not).
  [[nodiscard]] bool empty() const { return values_.empty(); }
  /// f at x held to [lo, hi], interpolated linearly between the two nearest steps.
  [[nodiscard]] double operator()(double x) const {
    const double t = (std::clamp(x, lo_, hi_) - lo_) * per_;
    if (!(t >= 0)) return std::numeric_limits<double>::quiet_NaN();  // before the cast
    const auto i = static_cast<std::size_t>(t);
    const double f = t - static_cast<double>(i);
    return values_[i] + f * (values_[i + 1] - values_[i]);
  }

 private:
  std::vector<double> values_;
  double lo_ = 0, hi_ = 0, per_ = 0;
};

}  // namespace linksight::sim
