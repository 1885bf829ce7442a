#include "linksight/tracker/format.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <algorithm>

namespace linksight {

namespace {

// v with `digits` significant digits, as %g would write it but without %g's switch to
// scientific notation for whole numbers: fixed for decimal exponents in [-4, 17)
// ("50", "0.0001", "473.5"), scientific otherwise ("5.4e-05", "1e+300").
std::string decimal(double v, int digits) {
  char buf[64];
  auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::scientific, digits - 1);
  const std::string sci(buf, r.ptr);
  const int exponent = std::atoi(sci.c_str() + sci.find('e') + 1);
  if (exponent < -4 || exponent >= 17) return sci;
  r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed,
                    std::max(0, digits - 1 - exponent));
  return std::string(buf, r.ptr);
}

// Significant digits of the shortest text that reads back as v.
int shortest_digits(double v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::scientific);
  int digits = 0;
  for (const char* c = buf; c < r.ptr && *c != 'e'; ++c) digits += *c >= '0' && *c <= '9';
  return digits;
}

}  // namespace

std::string format_shortest(double v, double scale) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  if (scale != 1.0) {
    const double x = v / scale;
    for (int digits = 1; digits <= 17; ++digits) {
      const std::string t = decimal(x, digits);
      double d = 0;
      std::from_chars(t.data(), t.data() + t.size(), d);
      if (d * scale == v) return t;
    }
    return decimal(x, shortest_digits(x));  // no decimal reads back exactly: the nearest
  }
  return decimal(v, shortest_digits(v));
}

std::string format_fixed(double v, int decimals) {
  if (!std::isfinite(v)) return "nan";
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed, decimals);
  if (r.ec == std::errc()) return std::string(buf, r.ptr);
  // Beyond the buffer (|v| > 1e40 or so): still fixed, just longer.
  std::string s(static_cast<std::size_t>(std::snprintf(nullptr, 0, "%.*f", decimals, v)) + 1, '\0');
  s.resize(static_cast<std::size_t>(std::snprintf(s.data(), s.size(), "%.*f", decimals, v)));
  return s;
}

}  // namespace linksight
