#pragma once
/// @file Sweeps: a deterministic grid of short episodes over any scene keys, split into
/// shards (one per process or Slurm array element) and merged back into one table.
///
/// A cell is one point of the grid: the base scene with one value per axis applied as
/// `--set key=value` overrides. Its seed is derived from its values, never from its
/// index or from who runs it, so a cell's row is the same on any machine and in any shard.

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "linksight/sim/external_tracker.hpp"
#include "linksight/tracker/limits.hpp"
#include "linksight/sim/scene.hpp"
#include "linksight/tracker/tracker.hpp"

namespace linksight::sim {

struct PhysicsRecording;  // episode.hpp

/// One axis: a scene key (as for --set; `scene` takes scene files) and its values.
struct SweepAxis {
  std::string key;
  std::vector<std::string> values;
};

/// "key=v1,v2,..." as given to --axis. Throws io::InputError naming the argument.
[[nodiscard]] SweepAxis parse_axis(const std::string& arg);
/// A grid file: `axes:` a list of one-key maps, `- noise.scale: [0, 1, 2]`. Throws
/// io::InputError naming the file, the line and the key.
[[nodiscard]] std::vector<SweepAxis> read_grid(const std::filesystem::path& file);

// kMaxSweepCells: linksight/tracker/limits.hpp.

struct SweepSpec {
  std::filesystem::path scene;     ///< base scene; an axis `scene` replaces it per cell
  std::vector<SweepAxis> axes;     ///< first axis slowest: cell index is row-major
  std::vector<std::string> set;    ///< overrides applied to every cell, before the axes
  std::vector<TrackerMode> modes;  ///< compared on each cell's frames; empty: the scene's mode
  bool scene_mode = true;  ///< as EpisodeOptions::scene_mode (false: external trackers only)
  /// Trackers outside linksight, after the modes (the command line's --tracker; the
  /// manifest records them to check that shards agree, and never starts one).
  std::vector<ExternalTrackerSpec> external;
  int frames = 0;                  ///< camera frames per cell; 0: the scene's duration
  /// Throws std::invalid_argument naming the problem: no scene, no axis, an axis without
  /// values, a key given twice, a value with a quote or line break, too many cells.
  void validate() const;
  [[nodiscard]] std::size_t cells() const;
  /// Rows per cell: one per compared tracker (mode or external).
  [[nodiscard]] std::size_t modes_per_cell() const {
    return (modes.empty() && scene_mode ? 1 : modes.size()) + external.size();
  }
};

struct SweepCell {
  std::size_t index = 0;
  std::vector<std::string> values;     ///< one per axis
  std::filesystem::path scene;         ///< the scene file of this cell
  std::vector<std::string> overrides;  ///< spec.set, then key=value per axis (not `scene`)
  /// The cell's seed: the value of a `seed` axis, else derived from the base scene's seed
  /// and every axis key=value of the cell.
  std::uint64_t seed = 0;
};
/// Cell `index` of the grid (index < spec.cells()). Loads the scene to read its seed.
[[nodiscard]] SweepCell sweep_cell(const SweepSpec& spec, std::size_t index);
/// The scene cell `index` runs: the base scene (or its `scene` value) with the cell's
/// overrides, and its seed. For callers that run the episode themselves.
[[nodiscard]] Scene sweep_cell_scene(const SweepSpec& spec, std::size_t index);

/// A digest (16 hex digits) of what determines a sweep's cells: the scene path, axes,
/// --set overrides, compared modes and trackers, frames, and the bytes of every scene file
/// a cell loads (not of the mesh files a scene names: a mesh changed mid-sweep is not
/// seen). The manifest records it when the sweep begins, every shard row, cell record and
/// .failed.csv row carries it, and a file whose digest differs is another sweep's.
[[nodiscard]] std::string sweep_digest(const SweepSpec& spec);

/// The deterministic columns: cell, mode, one per axis, seed, then the metrics (lengths
/// in mm, as the names say).
[[nodiscard]] std::vector<std::string> sweep_columns(const SweepSpec& spec);
/// The timing columns: cell, mode, then tracker time and the cell's wall time.
[[nodiscard]] std::vector<std::string> sweep_timing_columns();

/// One row per (cell, mode): the values of sweep_columns() and sweep_timing_columns(),
/// as text (shortest round-trip decimal, `nan` where undefined).
struct SweepRow {
  std::size_t cell = 0;
  std::size_t mode = 0;  ///< position of the row's mode among the cell's modes
  std::vector<std::string> values, timing;
  /// An external tracker's lost frames in words ("" for none): how many, and the first
  /// one's frame and reason (the tables count them in lost_frames).
  std::string lost_note;
};

/// Whether every cell of the sweep has the same physics: each axis key lies under `seed`,
/// `noise`, `occlusion`, `occluders`, `background`, `segmentation`, `tracker` or
/// `external`, which the sensor, the cloud and the trackers read and the world does not
/// (make_world: chain, world, base, actions; the frame times: camera). Its cells may then
/// replay one cell's physics (SweepShared).
[[nodiscard]] bool shares_world(const SweepSpec& spec);

/// What the cells one process runs share: where shares_world(spec), the physics of the
/// first cell it runs to the end, which the others replay (PhysicsRecording) instead of
/// stepping Bullet again, with the same rows bit for bit. Not for episodes of more than
/// kMaxSharedPhysicsFrames frames: a recording keeps about 2.2 kB a frame.
struct SweepShared {
  std::shared_ptr<const PhysicsRecording> physics;
};
/// At most 30,000 frames (about 66 MB) recorded for a sweep's cells to share; a longer
/// episode runs its own world in every cell.
inline constexpr int kMaxSharedPhysicsFrames = 30000;

/// Runs one cell's episode (sensor threads: 0 = OpenMP default; results do not depend
/// on it). Throws io::InputError for a bad scene or override, naming it, and
/// ExternalTrackerError when an external tracker dies or hangs (the cell failed).
/// `shared` (optional): kept from cell to cell of one sweep (see SweepShared).
[[nodiscard]] std::vector<SweepRow> run_cell(const SweepSpec& spec, std::size_t index,
                                             int threads,
                                             const std::atomic<bool>* cancel = nullptr,
                                             SweepShared* shared = nullptr);

/// The cells shard `shard` of `count` runs: those with index % count == shard.
[[nodiscard]] std::vector<std::size_t> shard_cells(const SweepSpec& spec, int shard, int count);
/// "shard_I_of_N.csv"
[[nodiscard]] std::string shard_file_name(int shard, int count);

/// The sweep's manifest, DIR/sweep.json: what every shard and the merge agree on.
/// write_manifest creates DIR and the file, or checks that an existing one describes the
/// same sweep (throws io::InputError naming what differs).
void write_manifest(const std::filesystem::path& dir, const SweepSpec& spec);
/// Reads DIR/sweep.json; throws io::InputError naming the file when missing or bad.
[[nodiscard]] SweepSpec read_manifest(const std::filesystem::path& dir);

/// A cell whose external tracker failed: no rows, the error instead.
struct SweepFailure {
  std::size_t cell = 0;
  std::string error;
};

/// Writes DIR/shard_I_of_N.csv atomically: every deterministic column, then the timing
/// columns after the cell and mode; and, when cells failed, DIR/shard_I_of_N.failed.csv
/// (`cell,error`, the error on one line), else removes a stale one. A shard with failed
/// cells is not complete: a re-run redoes it.
void write_shard(const std::filesystem::path& dir, const SweepSpec& spec, int shard, int count,
                 const std::vector<SweepRow>& rows,
                 const std::vector<SweepFailure>& failures = {});
/// The same from the shard's cell records (write_cell_record), read one cell at a time, so
/// that a shard's memory does not grow with its cells: every cell of the shard but the
/// failed ones must have its record (else io::InputError naming it).
void write_shard_from_records(const std::filesystem::path& dir, const SweepSpec& spec,
                              int shard, int count,
                              const std::vector<SweepFailure>& failures = {});
/// Whether DIR/shard_I_of_N.csv exists with the right columns and exactly its cells.
[[nodiscard]] bool shard_complete(const std::filesystem::path& dir, const SweepSpec& spec,
                                  int shard, int count);

/// Shard I of N run by one process at a time: an exclusive POSIX record lock (fcntl) on
/// the empty file DIR/shard_I_of_N.lock, held for the object's life and released by the
/// kernel however the process ends. Two runs of the same shard would remove each other's cell
/// records (issue 59). Throws InputError naming the lock file and the pid that holds it.
class ShardLock {
 public:
  ShardLock(const std::filesystem::path& dir, int shard, int count);
  ~ShardLock();
  ShardLock(const ShardLock&) = delete;
  ShardLock& operator=(const ShardLock&) = delete;

 private:
  int fd_ = -1;
};

/// A shard's cells as they complete (issue 19, F8): DIR/shard_I_of_N.cells/CELL.csv, the
/// cell's rows in the shard file's columns, written atomically as soon as the cell is
/// done, so that a shard killed (Ctrl-C, SIGKILL, a node lost) resumes where it stopped.
/// write_shard's caller removes them once the shard file is in place.
[[nodiscard]] std::filesystem::path cell_records_dir(const std::filesystem::path& dir, int shard,
                                                     int count);
void write_cell_record(const std::filesystem::path& dir, const SweepSpec& spec, int shard,
                       int count, std::size_t cell, const std::vector<SweepRow>& rows);
/// The rows a completed cell's record holds (lost_note empty), or nothing when there is
/// no record or it is not this sweep's whole cell (torn, foreign: run the cell again).
[[nodiscard]] std::optional<std::vector<SweepRow>> read_cell_record(
    const std::filesystem::path& dir, const SweepSpec& spec, int shard, int count,
    std::size_t cell);

struct MergeResult {
  std::size_t cells = 0, rows = 0, shard_files = 0;
  std::vector<SweepFailure> failed;  ///< cells that failed (in cells_failed.csv), by cell
};
/// Reads every DIR/shard_*_of_*.csv, checks that each cell of the manifest's grid is
/// there exactly once (throws io::InputError naming the missing and the doubled cells),
/// and writes DIR/cells.csv and DIR/cells_timing.csv sorted by cell, atomically. A cell
/// a shard's .failed.csv lists is not missing: it has no rows, and DIR/cells_failed.csv
/// lists it with its error.
MergeResult merge_sweep(const std::filesystem::path& dir);

}  // namespace linksight::sim
