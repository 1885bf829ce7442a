#pragma once
// Pieces that more than one subcommand needs: the --compare list, the shared options
// (--half, --draws, --seed), reading depth frames, and the plotting scripts.

#include <atomic>
#include <charconv>
#include <csignal>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "linksight/io/depth_png.hpp"
#include "linksight/io/error.hpp"
#include "linksight/io/frames.hpp"
#include "linksight/io/intrinsics.hpp"
#include "linksight/sim/depth_stats.hpp"
#include "linksight/sim/external_tracker.hpp"
#include "linksight/tracker/tracker.hpp"
#include <nlohmann/json.hpp>

namespace linksight::cli {

/// "paper,paper-centred" -> modes; errors name --compare and the bad item.
inline std::vector<TrackerMode> parse_compare(const std::string& list) {
  std::vector<TrackerMode> modes;
  std::stringstream ss(list);
  for (std::string item; std::getline(ss, item, ',');) {
    if (item.empty())
      throw std::invalid_argument("--compare '" + io::echo(list) + "': empty mode name");
    try {
      modes.push_back(parse_mode(item));
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(std::string("--compare: ") + e.what());
    }
  }
  return modes;
}

/// Set by Ctrl-C (SIGINT) or SIGTERM while an InterruptGuard lives: a command then stops
/// after its current step and keeps what it finished.
inline std::atomic<bool>& interrupted() {
  static std::atomic<bool> flag{false};
  return flag;
}
extern "C" inline void linksight_on_interrupt(int) { interrupted().store(true); }

/// Catches SIGINT and SIGTERM into interrupted() for its lifetime (clearing it first).
class InterruptGuard {
 public:
  InterruptGuard() {
    interrupted().store(false);
    previous_int_ = std::signal(SIGINT, linksight_on_interrupt);
    previous_term_ = std::signal(SIGTERM, linksight_on_interrupt);
  }
  ~InterruptGuard() {
    std::signal(SIGINT, previous_int_);
    std::signal(SIGTERM, previous_term_);
  }
  InterruptGuard(const InterruptGuard&) = delete;
  InterruptGuard& operator=(const InterruptGuard&) = delete;

 private:
  void (*previous_int_)(int) = SIG_DFL;
  void (*previous_term_)(int) = SIG_DFL;
};

/// --compare and --tracker NAME=COMMAND into built-in modes and external trackers: an item
/// of `compare` is a --tracker's NAME or a mode. Empty `compare`: no mode given (the
/// scene's) and every --tracker. A --tracker that --compare does not name is refused.
/// Returns whether the scene's own mode runs (sim::EpisodeOptions::scene_mode): only
/// without --compare; a --compare that names trackers alone runs those alone.
[[nodiscard]] inline bool split_compare(const std::string& compare,
                                        const std::vector<std::string>& trackers,
                                        std::vector<TrackerMode>& modes,
                                        std::vector<sim::ExternalTrackerSpec>& external) {
  std::vector<sim::ExternalTrackerSpec> given;
  for (const std::string& t : trackers) {
    given.push_back(sim::parse_external_tracker(t));
    for (std::size_t j = 0; j + 1 < given.size(); ++j)
      if (given[j].name == given.back().name)
        throw std::invalid_argument("--tracker '" + io::echo(t) + "': the name '" +
                                    io::echo(given.back().name) + "' is given twice");
  }
  modes.clear();
  external.clear();
  if (compare.empty()) {
    external = given;
    return true;
  }
  std::vector<bool> used(given.size(), false);
  std::stringstream ss(compare);
  for (std::string item; std::getline(ss, item, ',');) {
    if (item.empty())
      throw std::invalid_argument("--compare '" + io::echo(compare) + "': empty name");
    std::size_t k = 0;
    while (k < given.size() && given[k].name != item) ++k;
    if (k < given.size()) {
      if (used[k]) throw std::invalid_argument("--compare: '" + io::echo(item) + "' given twice");
      used[k] = true;
      external.push_back(given[k]);
      continue;
    }
    try {
      modes.push_back(parse_mode(item));
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(std::string("--compare: ") + e.what() +
                                  (given.empty() ? "" : ", or a --tracker NAME"));
    }
  }
  for (std::size_t k = 0; k < given.size(); ++k)
    if (!used[k])
      throw std::invalid_argument("--tracker '" + io::echo(given[k].name) +
                                  "=...': not in --compare '" + compare + "'");
  // Only a --compare without a built-in mode runs no scene mode (with modes named it does
  // not matter; true keeps the sweep manifest as before).
  return !modes.empty();
}

/// The 16-bit depth PNGs of `frames` (a directory or one file), each checked against the
/// size of `K` read from `intrinsics`; io::InputError names the file and both sizes.
inline std::vector<io::DepthImage> read_depth_frames(const std::string& frames,
                                                     const io::Intrinsics& K,
                                                     const std::string& intrinsics,
                                                     const std::string& command) {
  std::vector<io::DepthImage> images;
  for (const std::filesystem::path& p : io::list_frames(frames)) {
    if (!io::is_depth_png(p))
      throw io::InputError(p.string() + ": " + command + " reads 16-bit depth PNGs only");
    // The size from the header, before anything is decoded (a header may claim anything).
    const io::PngSize size = io::png_size(p);
    if (size.bit_depth != 16)
      throw io::InputError(p.string() + ": depth PNG must be 16-bit, this one is " +
                           std::to_string(size.bit_depth) + "-bit");
    if (size.width != K.width || size.height != K.height)
      throw io::InputError(p.string() + ": " + std::to_string(size.width) + "x" +
                           std::to_string(size.height) + " does not match the intrinsics (" +
                           intrinsics + ": " + std::to_string(K.width) + "x" +
                           std::to_string(K.height) + ")");
    images.push_back(io::read_depth_png(p));
  }
  return images;
}

/// --half: the frames of `half` (sim::FrameHalf, by name) out of `images`, the rest
/// dropped; io::InputError names `source`, the option and the value.
inline std::vector<io::DepthImage> take_half(std::vector<io::DepthImage> images,
                                             const io::Intrinsics& K, const std::string& half,
                                             const std::string& source) {
  std::vector<std::size_t> keep;
  try {
    keep = sim::frame_half(images, K, sim::parse_frame_half(half));
  } catch (const std::invalid_argument& e) {
    throw io::InputError(source + ": --half " + half + ": " + e.what());
  }
  if (keep.empty())
    throw io::InputError(source + ": --half " + half + ": no frame in that half of " +
                         std::to_string(images.size()));
  std::vector<io::DepthImage> out;
  for (const std::size_t k : keep) out.push_back(std::move(images[k]));
  return out;
}

/// The --half option (take_half), its values checked by name.
inline CLI::Option* add_half_option(CLI::App& app, std::string& half, const std::string& what) {
  std::vector<std::string> names;
  for (const sim::FrameHalf h : sim::kFrameHalves) names.emplace_back(sim::to_string(h));
  return app
      .add_option("--half", half,
                  what + ": all, or one half of its frames for a held-out check (fit on one, "
                         "compare on the other): even / odd positions in its order, or the "
                         "near / far half by median depth (docs/sensor.md)")
      ->check(CLI::IsMember(names))
      ->capture_default_str();
}

/// The --draws option (sim::RerenderFitParams::draws, rerender_surfaces' draws): noise draws
/// of each frame read together, 1-64; `what` says where it applies. Returned so that a
/// command can refuse it where it does not apply.
inline CLI::Option* add_draws_option(CLI::App& app, int& draws, const std::string& what) {
  return app
      .add_option("--draws", draws,
                  what + ": noise draws of each frame read together, so that the statistics "
                         "are the model's expectation rather than one draw's")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
}

/// The --seed option: a decimal whole number, 0 to 2^64 - 1. Anything else is refused by
/// name: CLI11 would wrap -1 (or " -1") to 2^64 - 1, read 010 as octal 8, and cap a number
/// past 2^64 - 1 at it, each without a word.
inline CLI::Option* add_seed_option(CLI::App& app, std::uint64_t& seed, const std::string& what) {
  return app.add_option("--seed", seed, what)
      ->transform(CLI::Validator(
          [](std::string& v) {
            std::uint64_t x = 0;
            const char* end = v.data() + v.size();
            const auto [at, ec] = std::from_chars(v.data(), end, x);
            if (v.empty() || ec != std::errc() || at != end)
              return "must be a whole number from 0 to " +
                     std::to_string(std::numeric_limits<std::uint64_t>::max()) + ", not '" + v +
                     "'";
            v = std::to_string(x);  // decimal, without leading zeros, for CLI11's conversion
            return std::string();
          },
          "SEED"))
      ->capture_default_str();
}

/// Degrees per radian: the reports' unit for angles (code keeps radians).
inline constexpr double kDegPerRad = 180.0 / 3.14159265358979323846;

/// A recording's statistics as tools/plot_fidelity.py draws them (lengths in mm, angles in
/// degrees, as the keys say).
inline nlohmann::json stats_series(const sim::DepthStats& s) {
  auto bins = [](const std::vector<sim::SigmaBin>& v, double unit) {
    nlohmann::json a = nlohmann::json::array();
    for (const auto& b : v)
      if (b.windows > 0)
        a.push_back({{"centre", b.centre * unit}, {"sigma_mm", b.sigma * 1e3}, {"windows", b.windows}});
    return a;
  };
  const sim::EdgeSide& shadow = s.projector_side < 0 ? s.near_left : s.near_right;
  // The structure (issue 20): quadratic-fit sigma by incidence, and the residual
  // correlation at lags 1..kCorrelationLags along rows and along columns (0 where a lag has
  // no pair of windows, as depth_stats reads it).
  return {{"sigma_by_depth", bins(s.sigma_by_depth, 1.0)},
          {"sigma_by_angle", bins(s.sigma_by_angle, kDegPerRad)},
          {"sigma_quad_by_angle", bins(s.sigma_quad_by_angle, kDegPerRad)},
          {"sigma_quad_by_depth", bins(s.sigma_quad_by_depth, 1.0)},
          {"correlation_rows", s.correlation_rows},
          {"correlation_cols", s.correlation_cols},
          {"shadow_gap_px", shadow.gap_px},
          {"shadow_width_px", shadow.width_px},
          {"hole_sizes_px", s.hole_sizes}};
}

/// `env`'s value if set, else the script in the source tree.
inline std::filesystem::path script_path(const char* env, const char* built_in) {
  if (const char* v = std::getenv(env)) return v;
  return built_in;
}

/// Runs `python3 SCRIPT DIR`; "" when it worked, else a note saying why there are no
/// figures (the data files are complete either way).
inline std::string run_plot_script(const std::filesystem::path& script,
                                   const std::filesystem::path& dir, bool quiet,
                                   const std::string& needs = "python3-matplotlib") {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(script, ec))
    return "no figures: " + script.string() + " not found";
  // Debian's interpreter first: python3-matplotlib is installed for it, and a python3
  // earlier in PATH (a virtualenv, pyenv) may lack it.
  const std::string python =
      std::filesystem::exists("/usr/bin/python3", ec) ? "/usr/bin/python3" : "python3";
  const std::string cmd = python + " '" + script.string() + "' '" + dir.string() + "'" +
                          (quiet ? " >/dev/null" : "") + " 2>&1";
  if (std::system(cmd.c_str()) != 0)
    return "no figures: " + script.string() + " failed (is " + needs + " installed?)";
  return "";
}

}  // namespace linksight::cli
