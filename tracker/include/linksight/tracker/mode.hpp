#pragma once
/// @file Tracker modes: each a named composition of policies (policy.hpp). The table in
/// tracker/src/modes.cpp is the only place that lists them; names, parsing, error text,
/// CLI help and the scene's accepted values all come from it. A new mode is one policy
/// file (if it needs a new part) plus one row there.

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "linksight/tracker/policy.hpp"

namespace linksight {

/// One row of the mode table.
struct ModeSpec {
  std::string_view name;     ///< as written in scenes, on the command line and in outputs
  std::string_view summary;  ///< one line for help texts
  PolicyRef<InitPolicy> init;
  PolicyRef<UpdatePolicy> update;
  PolicyRef<ReinitTrigger> reinit;
  PolicyRef<OutputPolicy> output;
};

/// Every mode, in table order (the first is the default).
[[nodiscard]] std::span<const ModeSpec> mode_table();

/// A mode: a row of mode_table(). The default is the table's first row (`chain-fit`).
class TrackerMode {
 public:
  constexpr TrackerMode() = default;
  /// The row at `index` of mode_table(); throws std::out_of_range past its end.
  [[nodiscard]] static TrackerMode at(std::size_t index);
  [[nodiscard]] const ModeSpec& spec() const;
  [[nodiscard]] std::size_t index() const { return index_; }
  friend constexpr auto operator<=>(TrackerMode, TrackerMode) = default;

 private:
  std::uint8_t index_ = 0;
};

/// Every mode, in table order.
[[nodiscard]] std::vector<TrackerMode> all_modes();
/// Every mode's name, in table order.
[[nodiscard]] std::vector<std::string> mode_names();
/// "chain-fit | paper | accelerated-som | paper-centred", for help texts.
[[nodiscard]] std::string mode_choices();
[[nodiscard]] std::string_view to_string(TrackerMode mode);
/// Throws std::invalid_argument naming the value and every mode.
[[nodiscard]] TrackerMode parse_mode(std::string_view name);

}  // namespace linksight
