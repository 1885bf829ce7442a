#pragma once
/// @file Seeds: one seed feeds every generator; sub-seeds are derived by name or index,
/// never by call order, so results do not depend on what ran before or on threads.

#include <cmath>
#include <cstdint>
#include <numbers>
#include <string_view>

namespace linksight {

/// splitmix64 finalizer: a fixed, portable bijective mix of 64 bits.
[[nodiscard]] constexpr std::uint64_t mix64(std::uint64_t z) {
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

/// splitmix64 step: advances `state` and returns the next value.
[[nodiscard]] constexpr std::uint64_t splitmix64(std::uint64_t& state) {
  return mix64(state += 0x9E3779B97F4A7C15ull);
}

/// 64 random bits to a uniform double in [0, 1) (the top 53 bits).
[[nodiscard]] constexpr double unit_interval(std::uint64_t bits) {
  return static_cast<double>(bits >> 11) * 0x1.0p-53;
}

/// A standard normal draw from two uniform draws in [0, 1) (Box–Muller; written out, as
/// the standard's distributions differ between libraries).
[[nodiscard]] inline double standard_normal(double u1, double u2) {
  return std::sqrt(-2.0 * std::log(1.0 - u1)) * std::cos(2 * std::numbers::pi * u2);
}

/// Sub-seed for item `index` (a frame, a pixel, a sweep cell) of stream `seed`.
[[nodiscard]] constexpr std::uint64_t derive_seed(std::uint64_t seed, std::uint64_t index) {
  return mix64(seed ^ mix64(index + 0x9E3779B97F4A7C15ull));
}

/// Sub-seed for a named stream ("noise", "occluder") of `seed` (FNV-1a of the name).
[[nodiscard]] constexpr std::uint64_t derive_seed(std::uint64_t seed, std::string_view name) {
  std::uint64_t h = 0xCBF29CE484222325ull;
  for (char c : name) h = (h ^ static_cast<unsigned char>(c)) * 0x100000001B3ull;
  return derive_seed(seed, h);
}

}  // namespace linksight
