#pragma once
// JSON numbers for the subcommands' reports; text numbers come from
// linksight/tracker/format.hpp (format_fixed, format_shortest), the one formatter.

#include <cmath>

#include <nlohmann/json.hpp>

#include "linksight/tracker/format.hpp"

namespace linksight::cli {

/// A JSON number, or null for NaN or Inf (JSON has neither).
inline nlohmann::json json_number(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

}  // namespace linksight::cli
