#include <gtest/gtest.h>

#include "linksight/tracker/seed.hpp"

namespace linksight {
namespace {

TEST(Seed, DerivedByNameOrIndexNotByOrder) {
  static_assert(derive_seed(1, std::uint64_t{0}) != derive_seed(1, std::uint64_t{1}));
  EXPECT_EQ(derive_seed(7, "noise"), derive_seed(7, "noise"));
  EXPECT_NE(derive_seed(7, "noise"), derive_seed(7, "occluder"));
  EXPECT_NE(derive_seed(7, std::uint64_t{3}), derive_seed(8, std::uint64_t{3}));
  std::uint64_t a = 5, b = 5;
  EXPECT_EQ(splitmix64(a), splitmix64(b));
  EXPECT_NE(splitmix64(a), splitmix64(a));
}

}  // namespace
}  // namespace linksight

namespace linksight {
namespace {
TEST(Seed, UnitIntervalCoversZeroToJustBelowOne) {
  EXPECT_EQ(unit_interval(0), 0.0);
  EXPECT_EQ(unit_interval(~0ull), 1.0 - 0x1.0p-53);
  EXPECT_EQ(unit_interval(1ull << 63), 0.5);
  EXPECT_EQ(unit_interval((1ull << 11) - 1), 0.0) << "only the top 53 bits count";
}
}  // namespace
}  // namespace linksight
