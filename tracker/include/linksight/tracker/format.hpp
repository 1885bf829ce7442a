#pragma once
/// @file Numbers as text: the one formatter for files, reports and error messages.

#include <string>

namespace linksight {

/// The shortest decimal text that reads back as the same double, fixed for decimal
/// exponents in [-4, 17) and scientific beyond ("0.1", "50", "5.4e-05", "1e+300"):
/// the same bits give the same bytes on any machine. "nan", "inf", "-inf" otherwise.
/// With a `scale`, the shortest text d with d * scale == v ("80" for 80 * pi/180 and
/// scale pi/180), so that a value written in degrees reads back to the same radians;
/// where no decimal does (about one radian value in ten), the nearest, which reads back
/// within one ulp.
[[nodiscard]] std::string format_shortest(double v, double scale = 1.0);

/// Fixed-point text with `decimals` decimals ("3.1416"); "nan" for NaN or Inf.
[[nodiscard]] std::string format_fixed(double v, int decimals);

}  // namespace linksight
