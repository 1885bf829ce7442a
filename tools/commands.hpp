#pragma once
// One function per subcommand; each registers its flags and returns the runner.

#include <CLI/CLI.hpp>
#include <functional>

namespace linksight::cli {

/// Exit codes shared by every subcommand.
inline constexpr int kExitOk = 0;
inline constexpr int kExitInternal = 1;
inline constexpr int kExitBadInput = 2;

using Runner = std::function<int()>;
Runner add_track(CLI::App& app);
Runner add_synth(CLI::App& app);
Runner add_devices(CLI::App& app);
Runner add_simulate(CLI::App& app);
Runner add_meshes(CLI::App& app);
Runner add_render(CLI::App& app);
Runner add_run(CLI::App& app);
Runner add_score(CLI::App& app);
Runner add_sweep(CLI::App& app);
Runner add_calibrate_noise(CLI::App& app);
Runner add_fidelity(CLI::App& app);

}  // namespace linksight::cli
