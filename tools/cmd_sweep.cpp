// linksight sweep: a grid of short episodes over scene keys, one row per cell, sharded
// by --shard or a Slurm job array, merged into DIR/cells.csv and heatmaps
// (tools/plot_sweep.py).
#include <malloc.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <memory>
#include <optional>

#include "cli_common.hpp"
#include "commands.hpp"
#include "format.hpp"
#include "linksight/io/error.hpp"
#include "linksight/sim/sweep.hpp"

namespace linksight::cli {
namespace {

namespace fs = std::filesystem;


struct SweepOptions {
  std::string scene, grid, out, compare, shard;
  std::vector<std::string> axes, set, trackers;
  int frames = 0;
  int threads = 0;
  bool figures = true;
  bool force = false;
  bool quiet = false;
};
struct MergeOptions {
  std::string dir;
  bool figures = true;
};

// "I/N" from --shard, else the Slurm array variables, else 0/1 (the whole grid).
std::pair<int, int> which_shard(const std::string& flag) {
  auto parse = [](const std::string& text, const std::string& what) {
    std::size_t used = 0;
    int v = -1;
    try {
      v = std::stoi(text, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != text.size() || text.empty())
      throw std::invalid_argument(what + " = '" + text + "': not an integer");
    return v;
  };
  if (!flag.empty()) {
    const auto slash = flag.find('/');
    if (slash == std::string::npos)
      throw std::invalid_argument("--shard '" + flag + "': expected I/N");
    const int i = parse(flag.substr(0, slash), "--shard I"),
              n = parse(flag.substr(slash + 1), "--shard N");
    if (n < 1 || i < 0 || i >= n)
      throw std::invalid_argument("--shard '" + flag + "': expected 0 <= I < N");
    return {i, n};
  }
  const char* id = std::getenv("SLURM_ARRAY_TASK_ID");
  const char* count = std::getenv("SLURM_ARRAY_TASK_COUNT");
  if (id && count) {
    // Arrays may start anywhere (--array=1-8): shards count from the array's minimum.
    const char* min = std::getenv("SLURM_ARRAY_TASK_MIN");
    const int i = parse(id, "SLURM_ARRAY_TASK_ID") - (min ? parse(min, "SLURM_ARRAY_TASK_MIN") : 0);
    const int n = parse(count, "SLURM_ARRAY_TASK_COUNT");
    if (n < 1 || i < 0 || i >= n)
      throw std::invalid_argument("Slurm array task " + std::string(id) + " of " + count +
                                  ": not a shard (expected a contiguous --array)");
    return {i, n};
  }
  return {0, 1};
}

void progress(std::size_t done, std::size_t total, double elapsed_s, int shard, int count) {
  constexpr std::size_t kWidth = 30;
  const std::size_t filled = total > 0 ? done * kWidth / total : kWidth;
  const double rate = elapsed_s > 0 ? static_cast<double>(done) / elapsed_s : 0;
  std::cerr << "\r[" << std::string(filled, '#') << std::string(kWidth - filled, '.') << "] "
            << done << "/" << total << " cells";
  if (count > 1) std::cerr << " (shard " << shard << "/" << count << ")";
  std::cerr << ", " << format_fixed(rate, 2) << " cells/s";
  if (rate > 0) std::cerr << ", " << format_fixed(static_cast<double>(total - done) / rate, 0) << " s left ";
  std::cerr << std::flush;
}

int merge_and_report(const fs::path& dir, bool figures, bool quiet) {
  const sim::MergeResult m = sim::merge_sweep(dir);
  if (!quiet)
    std::cout << "merged " << m.rows << " rows of " << m.cells << " cells from " << m.shard_files
              << " shard file(s): " << (dir / "cells.csv").string() << ", "
              << (dir / "cells_timing.csv").string() << "\n";
  if (!m.failed.empty()) {
    std::cerr << "linksight: warning: " << m.failed.size() << " cell(s) failed and have no rows ("
              << (dir / "cells_failed.csv").string() << "):";
    // A cell's error comes from a shard's .failed.csv: one printable line each.
    for (const sim::SweepFailure& f : m.failed)
      std::cerr << "\n  cell " << f.cell << ": " << io::printable_line(f.error);
    std::cerr << "\n";
  }
  if (figures) {
    const std::string note = run_plot_script(
        script_path("LINKSIGHT_SWEEP_PLOT_SCRIPT", LINKSIGHT_SWEEP_PLOT_SCRIPT), dir, quiet);
    if (!note.empty()) {
      std::cerr << "linksight: warning: " << io::printable_line(note) << "\n";
    } else if (!quiet) {
      std::cout << "heatmaps: " << (dir / "figures").string() << "/\n";
    }
  }
  return kExitOk;
}

int run_sweep(const SweepOptions& o) {
  if (o.out.empty()) throw std::invalid_argument("--out: required (the sweep directory)");
  if (o.threads < 0)
    throw std::invalid_argument("--threads = " + std::to_string(o.threads) + ": must be >= 0");
  sim::SweepSpec spec;
  spec.scene = o.scene;
  if (!o.grid.empty()) spec.axes = sim::read_grid(o.grid);
  for (const std::string& a : o.axes) spec.axes.push_back(sim::parse_axis(a));
  spec.set = o.set;
  spec.scene_mode = split_compare(o.compare, o.trackers, spec.modes, spec.external);
  spec.frames = o.frames;
  spec.validate();
  const auto [shard, count] = which_shard(o.shard);
  const fs::path dir = o.out;
  // The first cell loads now: a bad scene or override fails before anything is written.
  (void)sim::sweep_cell(spec, 0);
  // One process per shard, from before --force clears anything until the shard file is
  // written and its records removed.
  {
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) throw io::InputError(dir.string() + ": cannot create the sweep directory");
  }
  const sim::ShardLock lock(dir, shard, count);
  if (o.force && fs::exists(dir / "sweep.json")) {
    for (const auto& e : fs::directory_iterator(dir)) {
      const std::string name = e.path().filename().string();
      if (name.ends_with(".lock")) continue;  // another shard's may be held
      if (name == "sweep.json" || name.rfind("shard_", 0) == 0 || name.rfind("cells", 0) == 0)
        fs::remove_all(e.path());  // shard_I_of_N.cells/ too
    }
  }
  sim::write_manifest(dir, spec);
  const std::vector<std::size_t> cells = sim::shard_cells(spec, shard, count);
  if (sim::shard_complete(dir, spec, shard, count)) {
    if (!o.quiet)
      std::cout << "shard " << shard << "/" << count << " is complete in " << dir.string()
                << ": skipped\n";
  } else {
    std::optional<InterruptGuard> guard(std::in_place);
    const bool bar = !o.quiet && isatty(fileno(stderr));
    const auto t0 = std::chrono::steady_clock::now();
    // The rows are not kept: the shard file is written from the cells' records, so that
    // the shard's memory does not grow with its cells.
    std::vector<sim::SweepFailure> failures;
    std::size_t resumed = 0;
    // Where no axis moves the world, the shard's cells replay its first run cell's physics.
    sim::SweepShared shared;
    for (std::size_t k = 0; k < cells.size() && !interrupted(); ++k) {
      try {
        // A cell an earlier run of this shard completed (it was killed or stopped later).
        std::optional<std::vector<sim::SweepRow>> done =
            sim::read_cell_record(dir, spec, shard, count, cells[k]);
        resumed += done.has_value();
        if (!done) {
          done = sim::run_cell(spec, cells[k], o.threads, &interrupted(), &shared);
          sim::write_cell_record(dir, spec, shard, count, cells[k], *done);
          // A cell's buffers are freed between small rows and records that outlive them,
          // which leaves glibc's heap holes it does not give back: without this a shard's
          // memory grew by about 10 KB a cell (tests/soak, docs/reliability.md).
          malloc_trim(0);
        }
        for (const sim::SweepRow& r : *done) {
          if (!r.lost_note.empty()) {
            if (bar) std::cerr << "\n";
            std::cerr << "linksight: warning: cell " << cells[k] << ": "
                      << io::printable_line(r.lost_note) << "\n";
          }
        }
      } catch (const sim::ExternalTrackerInterrupted&) {
        break;  // interrupted() is set: the shard is not written
      } catch (const sim::ExternalTrackerError& e) {
        // The cell failed; the others go on. Listed in the shard's .failed.csv.
        failures.push_back({cells[k], e.what()});
        if (bar) std::cerr << "\n";
        std::cerr << "linksight: cell " << cells[k] << " failed: " << e.what() << "\n";
      }
      if (bar)
        progress(k + 1, cells.size(),
                 std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(),
                 shard, count);
    }
    if (bar) std::cerr << "\n";
    const bool stopped = interrupted();
    guard.reset();
    if (stopped) {
      std::cerr << "linksight: interrupted; shard " << shard << "/" << count
                << " not written; its completed cells are kept in "
                << sim::cell_records_dir(dir, shard, count).string()
                << " (run the same command again to resume)\n";
      return 130;
    }
    sim::write_shard_from_records(dir, spec, shard, count, failures);
    // The shard file holds every cell now; with failed cells the records stay, so that a
    // re-run runs only those again.
    if (failures.empty()) {
      std::error_code ec;
      fs::remove_all(sim::cell_records_dir(dir, shard, count), ec);
    }
    if (!o.quiet && resumed > 0)
      std::cout << "shard " << shard << "/" << count << ": " << resumed
                << " cells resumed from an earlier run\n";
    if (!o.quiet)
      std::cout << "shard " << shard << "/" << count << ": " << cells.size() << " cells -> "
                << (dir / sim::shard_file_name(shard, count)).string() << "\n";
    if (!failures.empty()) {
      std::cerr << "linksight: " << failures.size() << " of " << cells.size()
                << " cells of shard " << shard << "/" << count
                << " failed (an external tracker died or hung); the shard runs again when "
                   "started again\n";
      if (count == 1) (void)merge_and_report(dir, o.figures, o.quiet);
      return kExitBadInput;
    }
  }
  if (count == 1) return merge_and_report(dir, o.figures, o.quiet);
  if (!o.quiet)
    std::cout << "when all " << count << " shards are done: linksight sweep merge " << dir.string()
              << "\n";
  return kExitOk;
}

}  // namespace

Runner add_sweep(CLI::App& app) {
  auto o = std::make_shared<SweepOptions>();
  auto m = std::make_shared<MergeOptions>();
  app.add_option("--scene", o->scene, "base scene file (YAML)");
  app.add_option("--axis", o->axes,
                 "key=v1,v2,... one axis of the grid (repeatable; first axis slowest). Keys "
                 "as for --set; 'scene' takes scene files, 'seed' fixes the seed")
      ->take_all();
  app.add_option("--grid", o->grid, "YAML file with 'axes:', a list of {key: [values]}");
  app.add_option("--set", o->set, "key.path=value applied to every cell (repeatable)")->take_all();
  app.add_option("--compare", o->compare,
                 "trackers run on each cell's frames, comma-separated: modes (" +
                     mode_choices() + ") and --tracker NAMEs (default: the scene's "
                     "tracker.mode and every --tracker)");
  app.add_option("--tracker", o->trackers,
                 "NAME=COMMAND (repeatable): a tracker outside linksight, started per cell "
                 "(docs/protocol.md); compare it by NAME in --compare. Every shard must be given "
                 "the same");
  app.add_option("--out", o->out, "sweep directory (sweep.json, shard files, cells.csv, figures/)");
  app.add_option("--frames", o->frames, "camera frames per cell (default: the scene's duration)");
  app.add_option("--threads", o->threads, "sensor threads (0: OpenMP default)");
  app.add_option("--shard", o->shard,
                 "I/N: run the cells with index % N == I (default: SLURM_ARRAY_TASK_ID / "
                 "SLURM_ARRAY_TASK_COUNT when set, else all)");
  app.add_flag("!--no-figures", o->figures, "no heatmaps");
  app.add_flag("--force", o->force, "start over: remove DIR's sweep files first");
  app.add_flag("--quiet", o->quiet, "no progress bar and no report");
  CLI::App* merge = app.add_subcommand("merge", "Check that every cell is there exactly once and "
                                                "write cells.csv, cells_timing.csv and heatmaps.");
  merge->add_option("dir", m->dir, "sweep directory")->required();
  merge->add_flag("!--no-figures", m->figures, "no heatmaps");
  app.require_subcommand(0, 1);
  return [o, m, merge]() {
    if (merge->parsed()) return merge_and_report(m->dir, m->figures, false);
    return run_sweep(*o);
  };
}

}  // namespace linksight::cli
