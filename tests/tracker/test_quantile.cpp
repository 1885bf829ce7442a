// linksight::quantile (tracker/include/linksight/tracker/quantile.hpp): the one quantile
// every score, statistic and report uses.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "linksight/tracker/quantile.hpp"

namespace linksight {
namespace {

TEST(Quantile, MedianIsTheMiddleValueOrTheMeanOfTheTwo) {
  EXPECT_DOUBLE_EQ(quantile(std::vector<double>{5, 1, 3}, 0.5), 3.0);
  EXPECT_DOUBLE_EQ(quantile(std::vector<double>{4, 1, 3, 2}, 0.5), 2.5);
  EXPECT_DOUBLE_EQ(quantile(std::vector<int>{7}, 0.5), 7.0);
  // Bit for bit the mean of the two middle values, as the scores always wrote it.
  const double a = 0.1, b = 0.7;
  EXPECT_EQ(quantile(std::vector<double>{b, a}, 0.5), 0.5 * (a + b));
}

TEST(Quantile, InterpolatesBetweenOrderStatistics) {
  std::vector<int> v;
  for (int i = 20; i >= 1; --i) v.push_back(i);  // 1..20, reversed
  EXPECT_DOUBLE_EQ(quantile(v, 0.0), 1.0);
  EXPECT_DOUBLE_EQ(quantile(v, 1.0), 20.0);
  EXPECT_DOUBLE_EQ(quantile(v, 0.95), 19.05);  // h = 18.05
  EXPECT_DOUBLE_EQ(quantile(v, 0.25), 5.75);   // h = 4.75
  // Monotone in q.
  double last = -1;
  for (int k = 0; k <= 100; ++k) {
    const double x = quantile(v, k / 100.0);
    EXPECT_GE(x, last);
    last = x;
  }
}

TEST(Quantile, InPlaceEqualsTheCopyAndEmptyIsNaN) {
  std::vector<double> v = {3, 9, 1, 4, 4, 8, 0.5};
  const double q = quantile(v, 0.3);
  EXPECT_EQ(quantile_in_place(v, 0.3), q);
  EXPECT_TRUE(std::isnan(quantile(std::vector<double>{}, 0.5)));
}

}  // namespace
}  // namespace linksight
