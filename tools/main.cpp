// linksight: one CLI, one subcommand per file.
#include <iostream>
#include <map>

#include "commands.hpp"
#include "linksight/io/error.hpp"
#include "linksight/tracker/backend.hpp"

int main(int argc, char** argv) {
  using namespace linksight::cli;
  CLI::App app{
      "linksight: shape tracking of a deformable link (SOM, Li et al.) with a "
      "synthetic test harness.\nExit codes: 0 ok, 2 bad input or usage, 1 internal error."};
  app.require_subcommand(1);
  struct Subcommand {
    const char* name;
    const char* help;
    Runner (*add)(CLI::App&);
  };
  const Subcommand subcommands[] = {
      {"run",
       "The main job: simulate a scene, render it, run every compared tracker mode on the "
       "same frames and score them (frames.csv, nodes.csv, summary.json, figures).",
       add_run},
      {"sweep",
       "A grid of short episodes over scene keys (noise, occluders, tracker mode, seed, "
       "scene), one row per cell; shards for Slurm job arrays; 'sweep merge DIR' joins them.",
       add_sweep},
      {"score",
       "Score any tracker's nodes.csv against a recording's truth (from render) with the "
       "metrics of run: frames.csv, nodes.csv, summary.json, figures; several side by side.",
       add_score},
      {"track", "Track the link through a sequence of clouds (PLY or 16-bit depth PNG).",
       add_track},
      {"synth", "Write a synthetic cloud sequence of the link with its true nodes.", add_synth},
      {"simulate", "Run a scene's physics and write the true nodes at the camera rate.",
       add_simulate},
      {"render",
       "Render a scene with the simulated SR300: depth and label PNGs, clouds, truth in the "
       "camera frame.",
       add_render},
      {"calibrate-noise",
       "Measure a depth camera's noise and artefacts on a real recording (16-bit depth PNGs) "
       "and fit the simulated SR300's noise model: a report and a noise: block for scenes.",
       add_calibrate_noise},
      {"fidelity",
       "Compare a real recording with a simulated one: the calibrate-noise statistics side "
       "by side with their ratios, and overlaid figures.",
       add_fidelity},
      {"devices", "List every OpenCL platform and device, and what the opencl back end needs.",
       add_devices},
      {"meshes", "Write the component's triangle mesh (component.obj, metres, frame K).",
       add_meshes},
  };
  std::map<const CLI::App*, Runner> runners;
  for (const Subcommand& c : subcommands) {
    CLI::App* sub = app.add_subcommand(c.name, c.help);
    runners[sub] = c.add(*sub);
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::string what = e.what();
    for (char& c : what)
      if (c == '\n') c = ' ';  // CLI11's own line breaks
    std::cerr << "linksight: " << linksight::io::printable_line(what)
              << " (see linksight --help)\n";
    return kExitBadInput;
  }
  try {
    for (const CLI::App* sub : app.get_subcommands()) return runners.at(sub)();
  } catch (const linksight::io::InputError& e) {
    std::cerr << "linksight: " << linksight::io::printable_line(e.what()) << "\n";
    return kExitBadInput;
  } catch (const linksight::BackendUnavailable& e) {
    std::cerr << "linksight: " << linksight::io::printable_line(e.what()) << "\n";
    return kExitBadInput;
  } catch (const std::invalid_argument& e) {
    std::cerr << "linksight: " << linksight::io::printable_line(e.what()) << "\n";
    return kExitBadInput;
  } catch (const std::exception& e) {
    std::cerr << "linksight: internal error: " << linksight::io::printable_line(e.what()) << "\n";
    return kExitInternal;
  }
  return kExitInternal;
}
