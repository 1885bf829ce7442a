// The table of tracker modes: the one place that lists them.
#include <stdexcept>
#include <string>

#include "linksight/tracker/mode.hpp"

namespace linksight {
namespace {

// A new mode is a row here (and, if it needs a part that does not exist yet, one file
// under policy/). The first row is the default mode.
constexpr ModeSpec kModes[] = {
    {"chain-fit",
     "the chain itself (ours, issue 17): the ball centres fitted to the points by their "
     "distance to the component surfaces, every pitch exact, the shape held where nothing "
     "is seen, a constant-velocity start, re-initialization when the fit loses the points",
     kInitLsqCentred, kUpdateChainFit, kReinitNever, kOutputCentres},
    {"paper",
     "the paper's tracker: LSQ init, SOM mean, LSQ re-initialization when a node's "
     "neighbourhood is empty (Sec. IV)",
     kInitLsq, kUpdateSomMean, kReinitEmptyNeighbourhood, kOutputSurface},
    {"accelerated-som",
     "the paper's baseline (Croom 2010 / Baader 1994): straight-line or random-sample init, "
     "SOM mean, no re-initialization",
     kInitSom, kUpdateSomMean, kReinitNever, kOutputSurface},
    {"paper-centred",
     "paper, then each output node moved 2/3 r further from the camera along its viewing "
     "ray, from the seen surface to the ball centre (not in the paper)",
     kInitLsq, kUpdateSomMean, kReinitEmptyNeighbourhood, kOutputCentreOffset},
};
static_assert(std::size(kModes) < 256, "TrackerMode holds an 8-bit index");

}  // namespace

std::span<const ModeSpec> mode_table() { return kModes; }

TrackerMode TrackerMode::at(std::size_t index) {
  if (index >= std::size(kModes))
    throw std::out_of_range("TrackerMode::at(" + std::to_string(index) + "): the table has " +
                            std::to_string(std::size(kModes)) + " modes");
  TrackerMode m;
  m.index_ = static_cast<std::uint8_t>(index);
  return m;
}

const ModeSpec& TrackerMode::spec() const { return kModes[index_]; }

std::vector<TrackerMode> all_modes() {
  std::vector<TrackerMode> modes;
  for (std::size_t i = 0; i < std::size(kModes); ++i) modes.push_back(TrackerMode::at(i));
  return modes;
}

std::vector<std::string> mode_names() {
  std::vector<std::string> names;
  for (const ModeSpec& m : kModes) names.emplace_back(m.name);
  return names;
}

std::string mode_choices() {
  std::string s;
  for (const ModeSpec& m : kModes) s += (s.empty() ? "" : " | ") + std::string(m.name);
  return s;
}

std::string_view to_string(TrackerMode mode) { return mode.spec().name; }

TrackerMode parse_mode(std::string_view name) {
  for (std::size_t i = 0; i < std::size(kModes); ++i)
    if (kModes[i].name == name) return TrackerMode::at(i);
  // "expected a, b or c"
  std::string expected;
  for (std::size_t i = 0; i < std::size(kModes); ++i) {
    if (i > 0) expected += i + 1 == std::size(kModes) ? " or " : ", ";
    expected += kModes[i].name;
  }
  throw std::invalid_argument("unknown mode '" + std::string(name) + "' (expected " + expected +
                              ")");
}

}  // namespace linksight
