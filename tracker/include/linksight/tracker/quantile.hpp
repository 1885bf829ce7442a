#pragma once
/// @file The one quantile of linksight: scores, depth statistics, the noise fit and every
/// report use it, so a "median" or "p95" means the same number everywhere.

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <vector>

namespace linksight {

/// The q-quantile (0 <= q <= 1) of `values` by linear interpolation between order
/// statistics (Hyndman & Fan's definition 7, numpy's default): with h = q (n - 1) and
/// f = h - floor(h), (1 - f) x_(floor h) + f x_(floor h + 1) of the sorted values. The
/// median (q = 0.5) is the middle value, or the mean of the two middle ones. NaN when
/// `values` is empty. Reorders `values` (O(n): no full sort).
template <class T>
[[nodiscard]] double quantile_in_place(std::vector<T>& values, double q) {
  if (values.empty()) return std::numeric_limits<double>::quiet_NaN();
  const double h = q * static_cast<double>(values.size() - 1);
  const double lo = std::floor(h);
  const double f = h - lo;
  const auto k = static_cast<std::ptrdiff_t>(lo);
  std::nth_element(values.begin(), values.begin() + k, values.end());
  const double a = static_cast<double>(values[static_cast<std::size_t>(k)]);
  if (f == 0) return a;
  const double b = static_cast<double>(*std::min_element(values.begin() + k + 1, values.end()));
  return (1 - f) * a + f * b;
}

/// quantile_in_place on a copy.
template <class T>
[[nodiscard]] double quantile(std::vector<T> values, double q) {
  return quantile_in_place(values, q);
}

}  // namespace linksight
