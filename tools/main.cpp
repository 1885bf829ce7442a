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
  std::map<const CLI::App*, Runner> runners;
  {
    CLI::App* track = app.add_subcommand(
        "track", "Track the link through a sequence of clouds (PLY or 16-bit depth PNG).");
    runners[track] = add_track(*track);
    CLI::App* synth = app.add_subcommand(
        "synth", "Write a synthetic cloud sequence of the link with its true nodes.");
    runners[synth] = add_synth(*synth);
    CLI::App* simulate = app.add_subcommand(
        "simulate", "Run a scene's physics and write the true nodes at the camera rate.");
    runners[simulate] = add_simulate(*simulate);
    CLI::App* devices = app.add_subcommand(
        "devices", "List every OpenCL platform and device, and what the opencl back end needs.");
    runners[devices] = add_devices(*devices);
    CLI::App* meshes = app.add_subcommand(
        "meshes", "Write the component's triangle mesh (component.obj, metres, frame K).");
    runners[meshes] = add_meshes(*meshes);
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
      if (c == '\n') c = ' ';
    std::cerr << "linksight: " << what << " (see linksight --help)\n";
    return kExitBadInput;
  }
  try {
    for (const CLI::App* sub : app.get_subcommands()) return runners.at(sub)();
  } catch (const linksight::io::InputError& e) {
    std::cerr << "linksight: " << e.what() << "\n";
    return kExitBadInput;
  } catch (const linksight::BackendUnavailable& e) {
    std::cerr << "linksight: " << e.what() << "\n";
    return kExitBadInput;
  } catch (const std::invalid_argument& e) {
    std::cerr << "linksight: " << e.what() << "\n";
    return kExitBadInput;
  } catch (const std::exception& e) {
    std::cerr << "linksight: internal error: " << e.what() << "\n";
    return kExitInternal;
  }
  return kExitInternal;
}
