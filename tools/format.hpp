#pragma once
// Number formatting shared by the subcommands' reports.

#include <cmath>
#include <iomanip>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

namespace linksight::cli {

/// Fixed-point text with `precision` decimals; "nan" for NaN or Inf.
inline std::string fmt(double v, int precision) {
  if (!std::isfinite(v)) return "nan";
  std::ostringstream s;
  s << std::fixed << std::setprecision(precision) << v;
  return s.str();
}

/// A JSON number, or null for NaN or Inf (JSON has neither).
inline nlohmann::json json_number(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

}  // namespace linksight::cli
