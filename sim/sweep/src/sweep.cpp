#include "linksight/sim/sweep.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "linksight/io/atomic_file.hpp"
#include "linksight/io/csv.hpp"
#include "linksight/io/error.hpp"
#include "linksight/io/json_input.hpp"
#include "linksight/sim/episode.hpp"
#include "linksight/sim/scene.hpp"
#include "linksight/sim/yaml.hpp"
#include "linksight/tracker/format.hpp"
#include "linksight/tracker/seed.hpp"

namespace linksight::sim {
namespace fs = std::filesystem;
namespace {

constexpr const char* kManifest = "sweep.json";
// 2: the manifest and every shard row carry the sweep's digest (sweep_digest).
constexpr int kManifestVersion = 2;
// The last column of a shard file and a cell record: the sweep's digest, checked on every
// read and dropped from the merged tables.
constexpr const char* kDigestColumn = "sweep_digest";

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t") - b + 1);
}


// A metric as the tables write it: counts as integers, NaN as "nan".
std::string metric_text(const EpisodeMetric& m) {
  if (m.integer && !std::isnan(m.value)) return std::to_string(static_cast<long>(m.value));
  return format_shortest(m.value);
}
const char* const kTiming[] = {"cell", "mode", "time_ms_mean", "time_ms_p95", "time_ms_max",
                               "cell_wall_s"};

std::string csv_line(const std::vector<std::string>& fields) {
  std::string s;
  for (std::size_t i = 0; i < fields.size(); ++i) s += (i ? "," : "") + fields[i];
  return s + "\n";
}

// A shard file's header: the deterministic columns, then the timing columns after cell
// and mode.
std::vector<std::string> shard_columns(const SweepSpec& spec) {
  std::vector<std::string> c = sweep_columns(spec);
  for (std::size_t i = 2; i < std::size(kTiming); ++i) c.emplace_back(kTiming[i]);
  c.emplace_back(kDigestColumn);
  return c;
}

std::size_t parse_index(const std::string& s, const fs::path& path) {
  std::size_t v = 0;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  if (r.ec != std::errc() || r.ptr != s.data() + s.size())
    throw io::InputError(path.string() + ": cell '" + io::echo(s) + "' is not an index");
  return v;
}

// "3, 7-9, 12" for a sorted list, the first `limit` runs and a count of the rest.
std::string ranges(const std::vector<std::size_t>& v, std::size_t limit = 8) {
  std::string s;
  std::size_t runs = 0, i = 0;
  while (i < v.size()) {
    std::size_t j = i;
    while (j + 1 < v.size() && v[j + 1] == v[j] + 1) ++j;
    if (runs < limit) {
      if (runs) s += ", ";
      s += std::to_string(v[i]);
      if (j > i) {
        s += '-';
        s += std::to_string(v[j]);
      }
    }
    ++runs;
    i = j + 1;
  }
  if (runs > limit) s += " and " + std::to_string(runs - limit) + " more runs";
  return s;
}

// "shard_<digits>_of_<digits>.csv"
bool is_shard_file_name(const std::string& name) {
  const auto digits = [&](std::size_t& at) {
    const std::size_t from = at;
    while (at < name.size() && name[at] >= '0' && name[at] <= '9') ++at;
    return at > from;
  };
  std::size_t at = 0;
  const auto literal = [&](std::string_view lit) {
    if (name.compare(at, lit.size(), lit) != 0) return false;
    at += lit.size();
    return true;
  };
  return literal("shard_") && digits(at) && literal("_of_") && digits(at) && literal(".csv") &&
         at == name.size();
}

}  // namespace

SweepAxis parse_axis(const std::string& arg) {
  const auto eq = arg.find('=');
  if (eq == std::string::npos || eq == 0)
    throw io::InputError("--axis '" + io::echo(arg) + "': expected key=v1,v2,...");
  SweepAxis a;
  a.key = trim(arg.substr(0, eq));
  for (const std::string& v : io::split(arg.substr(eq + 1), ',')) {
    if (trim(v).empty()) throw io::InputError("--axis '" + io::echo(arg) + "': empty value");
    a.values.push_back(trim(v));
  }
  if (a.values.empty()) throw io::InputError("--axis '" + io::echo(arg) + "': no values");
  return a;
}

std::vector<SweepAxis> read_grid(const fs::path& file) {
  const YAML::Node root = yaml::load_file(file, "grid");
  const yaml::Reader r(file.string());
  if (!root.IsMap() || !root["axes"])
    throw io::InputError(file.string() + ": expected a map with the key 'axes'");
  r.only(root, "", {"axes"});
  const YAML::Node axes = root["axes"];
  if (!axes.IsSequence() || axes.size() == 0)
    r.fail(axes, "axes", "expected a non-empty list of {key: [values]}");
  std::vector<SweepAxis> out;
  for (const YAML::Node& item : axes) {
    if (!item.IsMap() || item.size() != 1) r.fail(item, "axes", "each item is one key: [values]");
    const auto kv = *item.begin();
    SweepAxis a;
    a.key = r.key_text(kv.first, "axes");
    if (!kv.second.IsSequence() || kv.second.size() == 0)
      r.fail(kv.second, a.key, "expected a non-empty list of values");
    for (const YAML::Node& v : kv.second) {
      if (!v.IsScalar()) r.fail(v, a.key, "values must be scalars");
      a.values.push_back(v.Scalar());
    }
    out.push_back(std::move(a));
  }
  return out;
}

void SweepSpec::validate() const {
  if (axes.empty()) throw std::invalid_argument("sweep: no axis (give --axis or --grid)");
  std::set<std::string> keys;
  bool scene_axis = false;
  for (const SweepAxis& a : axes) {
    if (a.key.empty()) throw std::invalid_argument("sweep: an axis without a key");
    if (a.key == "cell" || a.key == "mode" || a.key == "cell_seed")
      throw std::invalid_argument("sweep: axis '" + io::echo(a.key) +
                                  "' clashes with a column name");
    if (!keys.insert(a.key).second)
      throw std::invalid_argument("sweep: axis '" + io::echo(a.key) + "' given twice");
    if (a.values.empty())
      throw std::invalid_argument("sweep: axis '" + io::echo(a.key) + "' has no values");
    for (const std::string& v : a.values)
      if (v.find_first_of("\",\n\r") != std::string::npos || v.empty())
        throw std::invalid_argument("sweep: axis '" + io::echo(a.key) + "' value '" + io::echo(v) +
                                    "': empty, or holds a quote, comma or line break");
    scene_axis = scene_axis || a.key == "scene";
  }
  if (scene.empty() && !scene_axis)
    throw std::invalid_argument("sweep: no scene (give --scene or an axis 'scene')");
  std::set<TrackerMode> seen;
  for (const TrackerMode m : modes)
    if (!seen.insert(m).second)
      throw std::invalid_argument("sweep: mode " + std::string(to_string(m)) + " given twice");
  if (modes.empty() && !scene_mode && external.empty())
    throw std::invalid_argument("sweep: no tracker to compare (no mode, no external tracker)");
  std::set<std::string> names;
  for (const TrackerMode m : modes) names.emplace(to_string(m));
  for (const ExternalTrackerSpec& e : external)
    if (e.name.empty() || !names.insert(e.name).second)
      throw std::invalid_argument("sweep: tracker '" + io::echo(e.name) + "' given twice");
  if (frames < 0)
    throw std::invalid_argument("sweep: frames = " + std::to_string(frames) + ": must be >= 0");
  double n = 1;
  for (const SweepAxis& a : axes) n *= static_cast<double>(a.values.size());
  if (n > static_cast<double>(kMaxSweepCells))
    throw std::invalid_argument("sweep: " + format_shortest(n) + " cells: at most " +
                                std::to_string(kMaxSweepCells));
}

std::size_t SweepSpec::cells() const {
  std::size_t n = 1;
  for (const SweepAxis& a : axes) n *= a.values.size();
  return n;
}

namespace {
// Cell `index`'s value of each axis (row-major: the last axis varies fastest).
std::vector<std::string> cell_values(const SweepSpec& spec, std::size_t index) {
  std::vector<std::string> values(spec.axes.size());
  std::size_t rest = index;
  for (std::size_t k = spec.axes.size(); k-- > 0;) {
    values[k] = spec.axes[k].values[rest % spec.axes[k].values.size()];
    rest /= spec.axes[k].values.size();
  }
  return values;
}

// The cell and its loaded scene (seed set to the cell's): run_cell needs both, and a scene
// file is parsed once per cell.
std::pair<SweepCell, Scene> load_cell(const SweepSpec& spec, std::size_t index) {
  if (index >= spec.cells())
    throw std::invalid_argument("sweep: cell " + std::to_string(index) + " of " +
                                std::to_string(spec.cells()));
  SweepCell c;
  c.index = index;
  c.scene = spec.scene;
  c.overrides = spec.set;
  c.values = cell_values(spec, index);
  std::string key;
  bool seed_axis = false;
  std::vector<std::string> axis;  // applied after --set, and named --axis in errors
  for (std::size_t k = 0; k < spec.axes.size(); ++k) {
    const std::string& name = spec.axes[k].key;
    key += name + "=" + c.values[k] + ";";
    if (name == "scene") {
      c.scene = c.values[k];
    } else {
      axis.push_back(name + "=" + c.values[k]);
      seed_axis = seed_axis || name == "seed";
    }
  }
  c.overrides.insert(c.overrides.end(), axis.begin(), axis.end());
  Scene scene = load_scene(c.scene, spec.set, axis);
  c.seed = seed_axis ? scene.seed : derive_seed(scene.seed, std::string_view(key));
  scene.seed = c.seed;
  return {std::move(c), std::move(scene)};
}
}  // namespace

SweepCell sweep_cell(const SweepSpec& spec, std::size_t index) {
  return load_cell(spec, index).first;
}

Scene sweep_cell_scene(const SweepSpec& spec, std::size_t index) {
  return load_cell(spec, index).second;
}

std::vector<std::string> sweep_columns(const SweepSpec& spec) {
  std::vector<std::string> c = {"cell", "mode"};
  for (const SweepAxis& a : spec.axes) c.push_back(a.key);
  c.emplace_back("cell_seed");  // the seed the cell ran with
  for (const EpisodeMetric& m : episode_metrics(EpisodeSummary{})) c.emplace_back(m.name);
  return c;
}

std::vector<std::string> sweep_timing_columns() { return {std::begin(kTiming), std::end(kTiming)}; }

bool shares_world(const SweepSpec& spec) {
  // Keys the world never reads; anything else (an unknown key included) may move it.
  static constexpr std::string_view kSensorOnly[] = {"seed",       "noise",        "occlusion",
                                                      "occluders",  "background",   "segmentation",
                                                      "tracker",    "external"};
  for (const SweepAxis& a : spec.axes) {
    bool sensor_only = false;
    for (const std::string_view root : kSensorOnly)
      sensor_only = sensor_only ||
                    (a.key.compare(0, root.size(), root) == 0 &&
                     (a.key.size() == root.size() || a.key[root.size()] == '.' ||
                      a.key[root.size()] == '['));
    if (!sensor_only) return false;
  }
  return true;
}

std::vector<SweepRow> run_cell(const SweepSpec& spec, std::size_t index, int threads,
                               const std::atomic<bool>* cancel, SweepShared* shared) {
  const auto t0 = std::chrono::steady_clock::now();
  const auto [cell, scene] = load_cell(spec, index);
  EpisodeOptions o;
  o.frames = spec.frames;
  o.modes = spec.modes;
  o.scene_mode = spec.scene_mode;
  o.external = spec.external;
  o.cancel = cancel;
  o.threads = threads;
  o.chain_only_images = true;  // a cell writes numbers only, never an image
  const bool share = shared != nullptr && shares_world(spec) &&
                     camera_frames(scene, spec.frames) <= kMaxSharedPhysicsFrames;
  if (share) {
    o.replay = shared->physics;
    o.record = o.replay == nullptr;
  }
  Episode e(scene, o);
  const std::vector<std::string> names = e.names();
  const std::size_t m = names.size();
  std::vector<int> lost(names.size(), 0);
  std::vector<std::string> first(names.size());
  while (e.done() < e.frames()) {
    const EpisodeFrame& f = e.step();
    for (std::size_t k = 0; k < names.size(); ++k)
      if (!f.lost_details[k].empty() && lost[k]++ == 0)
        first[k] = "frame " + std::to_string(f.frame) + ": " + f.lost_details[k];
  }
  e.stop_external();
  if (share && !shared->physics) shared->physics = e.recording();
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const std::vector<EpisodeSummary> sums = e.summaries();
  std::vector<SweepRow> rows;
  for (std::size_t k = 0; k < m; ++k) {
    const EpisodeSummary& s = sums[k];
    SweepRow r;
    r.cell = index;
    r.mode = k;
    const std::string& mode = names[k];
    r.values = {std::to_string(index), mode};
    r.values.insert(r.values.end(), cell.values.begin(), cell.values.end());
    r.values.push_back(std::to_string(cell.seed));
    for (const EpisodeMetric& metric : episode_metrics(s)) r.values.push_back(metric_text(metric));
    r.timing = {std::to_string(index), mode, format_shortest(s.time.mean * 1e3), format_shortest(s.time.p95 * 1e3),
                format_shortest(s.time.max * 1e3), format_shortest(wall)};
    if (lost[k] > 0)
      r.lost_note = mode + ": " + std::to_string(lost[k]) + " frame(s) lost, the first (" +
                    first[k] + ")";
    rows.push_back(std::move(r));
  }
  return rows;
}

std::vector<std::size_t> shard_cells(const SweepSpec& spec, int shard, int count) {
  if (count < 1 || shard < 0 || shard >= count)
    throw std::invalid_argument("shard " + std::to_string(shard) + "/" + std::to_string(count) +
                                ": expected 0 <= I < N");
  std::vector<std::size_t> cells;
  for (std::size_t i = static_cast<std::size_t>(shard); i < spec.cells();
       i += static_cast<std::size_t>(count))
    cells.push_back(i);
  return cells;
}

std::string shard_file_name(int shard, int count) {
  return "shard_" + std::to_string(shard) + "_of_" + std::to_string(count) + ".csv";
}

namespace {
// The settings that determine a sweep's cells, as its manifest records them.
nlohmann::json settings_json(const SweepSpec& spec) {
  nlohmann::json j;
  j["scene"] = spec.scene.string();
  j["axes"] = nlohmann::json::array();
  for (const SweepAxis& a : spec.axes) j["axes"].push_back({{"key", a.key}, {"values", a.values}});
  j["set"] = spec.set;
  j["modes"] = nlohmann::json::array();
  for (const TrackerMode m : spec.modes) j["modes"].push_back(std::string(to_string(m)));
  // Written only when false (external trackers alone), so other manifests read as before.
  if (!spec.scene_mode) j["scene_mode"] = false;
  // Names and commands, to check that every shard compares the same trackers; a shard
  // starts the ones its own command line gives, never these.
  if (!spec.external.empty()) {
    j["external"] = nlohmann::json::array();
    for (const ExternalTrackerSpec& e : spec.external)
      j["external"].push_back({{"name", e.name}, {"command", e.command}});
  }
  j["frames"] = spec.frames;
  return j;
}

nlohmann::json manifest_json(const SweepSpec& spec) {
  nlohmann::json j = settings_json(spec);
  j["version"] = kManifestVersion;
  j["cells"] = spec.cells();
  j["digest"] = sweep_digest(spec);
  return j;
}

// The digest a manifest was written with.
std::string stored_digest(const fs::path& dir) {
  const fs::path path = dir / kManifest;
  const nlohmann::json j =
      nlohmann::json::parse(io::read_json_file(path, "no sweep manifest here"));
  const auto d = j.find("digest");
  const std::string digest = d != j.end() && d->is_string() ? d->get<std::string>() : "";
  if (digest.size() != 16 || digest.find_first_not_of("0123456789abcdef") != std::string::npos)
    throw io::InputError(path.string() + ": no digest of 16 hex digits");
  return digest;
}
}  // namespace

std::string sweep_digest(const SweepSpec& spec) {
  // FNV-1a, 64 bits, over each part with its length: not a defence against a forger, a
  // check that a file was made by this sweep.
  std::uint64_t h = 0xcbf29ce484222325ull;
  const auto add = [&](std::string_view part) {
    const std::string framed = std::to_string(part.size()) + ":";
    for (const std::string_view p : {std::string_view(framed), part})
      for (const char c : p) h = (h ^ static_cast<unsigned char>(c)) * 0x100000001b3ull;
  };
  add(settings_json(spec).dump());
  // The bytes of every scene file a cell loads: the base scene and each `scene` axis value.
  std::vector<fs::path> scenes;
  if (!spec.scene.empty()) scenes.push_back(spec.scene);
  for (const SweepAxis& a : spec.axes)
    if (a.key == "scene")
      for (const std::string& v : a.values) scenes.emplace_back(v);
  for (const fs::path& p : scenes) {
    // Only a regular file is read: a FIFO would block here (yaml::load_file refuses it).
    std::error_code ec;
    std::ifstream in;
    if (fs::is_regular_file(p, ec)) in.open(p, std::ios::binary);
    std::string bytes;
    char buf[4096];
    while (in.read(buf, sizeof buf) || in.gcount() > 0) {
      bytes.append(buf, static_cast<std::size_t>(in.gcount()));
      if (bytes.size() > yaml::kMaxFileBytes) break;  // load_scene refuses such a file
    }
    add(p.string());
    add(bytes);
  }
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(h));
  return hex;
}

void write_manifest(const fs::path& dir, const SweepSpec& spec) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir))
    throw io::InputError(dir.string() + ": cannot create the sweep directory");
  const fs::path path = dir / kManifest;
  const nlohmann::json want = manifest_json(spec);
  if (fs::exists(path)) {
    const SweepSpec have = read_manifest(dir);
    const nlohmann::json got = manifest_json(have);
    // `external` is there only when a sweep has external trackers. Both documents are
    // manifest_json's own (3 levels deep), so a dump is safe; echo bounds its length.
    const auto at = [](const nlohmann::json& j, const char* field) {
      return j.contains(field) ? j.at(field) : nlohmann::json(nullptr);
    };
    for (const char* field : {"scene", "axes", "set", "modes", "scene_mode", "external", "frames"}) {
      if (at(got, field) != at(want, field))
        throw io::InputError(path.string() + " describes another sweep: " + field + " is " +
                             io::echo(at(got, field).dump()) + ", this run has " +
                             io::echo(at(want, field).dump()) +
                             " (use another --out, or --force to start over)");
    }
    // The same settings, but a scene file changed since the sweep began: its cells would
    // mix two scenes.
    if (const std::string had = stored_digest(dir); had != want.at("digest").get<std::string>())
      throw io::InputError(path.string() + " describes another sweep: digest " + had +
                           ", this run has " + want.at("digest").get<std::string>() +
                           " (a scene file changed since the sweep began; use another --out, "
                           "or --force to start over)");
    return;
  }
  io::write_file_atomic(path, [&](std::ostream& os) { os << want.dump(2) << "\n"; });
}

SweepSpec read_manifest(const fs::path& dir) {
  const fs::path path = dir / kManifest;
  const std::string text =
      io::read_json_file(path, "no sweep manifest here (not a sweep directory?)");
  try {
    const nlohmann::json j = nlohmann::json::parse(text);
    // An integer JSON value, checked first: get<int>() of 2e35 is undefined behaviour
    // (found by fuzz_shard).
    const auto integer = [&](const char* key, long long hi) {
      const nlohmann::json& v = j.at(key);
      const bool ok = v.is_number_unsigned()
                          ? v.get<std::uint64_t>() <= static_cast<std::uint64_t>(hi)
                          : v.is_number_integer() && v.get<long long>() >= 0 &&
                                v.get<long long>() <= hi;
      if (!ok)
        throw io::InputError(path.string() + ": " + key + " " + io::json_summary(v) +
                             ": expected an integer in [0, " + std::to_string(hi) + "]");
      return v.get<long long>();
    };
    constexpr long long kIntMax = std::numeric_limits<int>::max();
    if (integer("version", kIntMax) != kManifestVersion)
      throw io::InputError(path.string() + ": version " + io::json_summary(j.at("version")) +
                           ", expected " + std::to_string(kManifestVersion));
    SweepSpec s;
    s.scene = j.at("scene").get<std::string>();
    for (const auto& a : j.at("axes"))
      s.axes.push_back({a.at("key").get<std::string>(),
                        a.at("values").get<std::vector<std::string>>()});
    s.set = j.at("set").get<std::vector<std::string>>();
    for (const auto& m : j.at("modes")) s.modes.push_back(parse_mode(m.get<std::string>()));
    s.scene_mode = j.value("scene_mode", true);
    if (j.contains("external"))
      for (const auto& e : j.at("external"))
        s.external.push_back({e.at("name").get<std::string>(), e.at("command").get<std::string>()});
    s.frames = static_cast<int>(integer("frames", kIntMax));
    s.validate();
    if (static_cast<std::size_t>(integer("cells", std::numeric_limits<long long>::max())) !=
        s.cells())
      throw io::InputError(path.string() + ": cells " + io::json_summary(j.at("cells")) +
                           " does not match its axes (" + std::to_string(s.cells()) + ")");
    return s;
  } catch (const nlohmann::json::exception& e) {
    throw io::InputError(path.string() + ": " + e.what());
  } catch (const std::invalid_argument& e) {
    throw io::InputError(path.string() + ": " + e.what());
  }
}

namespace {
// shard_I_of_N.failed.csv beside shard_I_of_N.csv.
fs::path failed_file(const fs::path& shard_file) {
  std::string name = shard_file.filename().string();
  name.replace(name.size() - 4, 4, ".failed.csv");
  return shard_file.parent_path() / name;
}
// An error on one line of a CSV without quoting.
std::string one_field(std::string s) {
  for (char& c : s)
    if (c == '\n' || c == '\r') c = '|';
    else if (c == ',') c = ';';
  return s;
}

// A row as the shard file and a cell's record hold it: the deterministic columns, then the
// timing columns after the cell and mode.
void write_row(std::ostream& os, const SweepRow& r, const std::string& digest) {
  std::vector<std::string> f = r.values;
  f.insert(f.end(), r.timing.begin() + 2, r.timing.end());
  f.push_back(digest);
  os << csv_line(f);
}

// The shard file and its .failed.csv; `rows` writes the rows after the header.
void write_shard_file(const fs::path& dir, const SweepSpec& spec, int shard, int count,
                      const std::vector<SweepFailure>& failures,
                      const std::function<void(std::ostream&)>& rows) {
  const fs::path file = dir / shard_file_name(shard, count);
  if (failures.empty()) {
    std::error_code ec;
    fs::remove(failed_file(file), ec);
  } else {
    // The sweep's digest on each row, as in the shard file: a shard whose cells all
    // failed has no other row to tell whose it is.
    const std::string digest = sweep_digest(spec);
    io::write_file_atomic(failed_file(file), [&](std::ostream& os) {
      os << "cell,error," << kDigestColumn << "\n";
      for (const SweepFailure& f : failures)
        os << f.cell << ',' << one_field(f.error) << ',' << digest << '\n';
    });
  }
  io::write_file_atomic(file, [&](std::ostream& os) {
    os << csv_line(shard_columns(spec));
    rows(os);
  });
}
}  // namespace

void write_shard(const fs::path& dir, const SweepSpec& spec, int shard, int count,
                 const std::vector<SweepRow>& rows, const std::vector<SweepFailure>& failures) {
  const std::string digest = sweep_digest(spec);
  write_shard_file(dir, spec, shard, count, failures, [&](std::ostream& os) {
    for (const SweepRow& r : rows) write_row(os, r, digest);
  });
}

void write_shard_from_records(const fs::path& dir, const SweepSpec& spec, int shard, int count,
                              const std::vector<SweepFailure>& failures) {
  std::set<std::size_t> failed;
  for (const SweepFailure& f : failures) failed.insert(f.cell);
  const std::string digest = sweep_digest(spec);
  write_shard_file(dir, spec, shard, count, failures, [&](std::ostream& os) {
    for (const std::size_t c : shard_cells(spec, shard, count)) {
      if (failed.count(c) != 0) continue;
      const std::optional<std::vector<SweepRow>> rows =
          read_cell_record(dir, spec, shard, count, c);
      if (!rows)
        throw io::InputError((cell_records_dir(dir, shard, count) / (std::to_string(c) + ".csv"))
                                 .string() +
                             ": cell " + std::to_string(c) +
                             "'s record is missing or torn (run the shard again)");
      for (const SweepRow& r : *rows) write_row(os, r, digest);
    }
  });
}

namespace {
// A shard row belongs to this sweep: its cell is in the grid, its axis values are that
// cell's, its tracker is one the manifest compares and, with a fixed --frames, it ran
// that many frames. A shard file copied in from another sweep with the same columns (other
// seeds, another --frames) is refused here, not merged (issue 19, F3). Throws InputError
// naming the file, the line and the field.
void check_shard_row(const SweepSpec& spec, const std::string& digest,
                     const std::vector<std::string>& header, const std::vector<std::string>& row,
                     const fs::path& path, int line) {
  const std::string at = path.string() + ":" + std::to_string(line) + ": ";
  const std::size_t cell = parse_index(row[0], path);
  if (cell >= spec.cells())
    throw io::InputError(at + "cell " + io::echo(row[0]) + " is beyond the grid's " +
                         std::to_string(spec.cells()) + " cells");
  const std::vector<std::string> values = cell_values(spec, cell);
  for (std::size_t k = 0; k < values.size(); ++k)
    if (row[2 + k] != values[k])
      throw io::InputError(at + "cell " + row[0] + "'s " + header[2 + k] + " is '" +
                           io::echo(row[2 + k]) + "', this sweep's grid has '" +
                           io::echo(values[k]) + "' (a shard of another sweep?)");
  bool known = spec.modes.empty() && spec.scene_mode;  // the scene's own mode: any mode
  if (known) {
    try {
      (void)parse_mode(row[1]);
    } catch (const std::invalid_argument&) {
      known = false;
    }
  }
  for (const TrackerMode m : spec.modes) known = known || row[1] == to_string(m);
  for (const ExternalTrackerSpec& e : spec.external) known = known || row[1] == e.name;
  if (!known)
    throw io::InputError(at + "tracker '" + io::echo(row[1]) + "' is not one this sweep compares " +
                         "(a shard of another sweep?)");
  if (spec.frames > 0) {
    const auto f = std::find(header.begin(), header.end(), "frames");
    if (f != header.end() &&
        row[static_cast<std::size_t>(f - header.begin())] != std::to_string(spec.frames))
      throw io::InputError(at + "cell " + row[0] + " ran " +
                           io::echo(row[static_cast<std::size_t>(f - header.begin())]) +
                           " frames, this sweep runs " + std::to_string(spec.frames) +
                           " (a shard of another sweep?)");
  }
  // Another sweep's shard with the same axes and frames (another --set or scene) has
  // the same columns and axis values: only the digest tells (issue 59).
  if (row.back() != digest)
    throw io::InputError(
        at + "its sweep digest is '" + io::echo(row.back()) + "', this sweep's is '" + digest +
        "' (a shard of another sweep: another scene, --set, axis, " + "frames or tracker)");
}
}  // namespace

namespace {
// A shard file or cell record of `spec` holding at most `cells` cells: a row per compared
// mode of each, and the shard's columns.
io::CsvLimits shard_limits(const SweepSpec& spec, std::size_t cells) {
  io::CsvLimits limits;
  limits.max_rows = cells * spec.modes_per_cell();
  limits.max_columns = shard_columns(spec).size();
  return limits;
}
}  // namespace

bool shard_complete(const fs::path& dir, const SweepSpec& spec, int shard, int count) {
  const fs::path path = dir / shard_file_name(shard, count);
  if (!fs::exists(path) || fs::exists(failed_file(path))) return false;
  try {
    const io::CsvTable f =
        io::read_csv(path, shard_limits(spec, shard_cells(spec, shard, count).size()));
    if (f.header != shard_columns(spec)) return false;
    const std::string digest = sweep_digest(spec);
    std::multiset<std::size_t> have;
    for (std::size_t i = 0; i < f.rows.size(); ++i) {
      check_shard_row(spec, digest, f.header, f.rows[i], path, f.lines[i]);
      have.insert(parse_index(f.rows[i][0], path));
    }
    std::multiset<std::size_t> want;
    for (const std::size_t c : shard_cells(spec, shard, count))
      for (std::size_t k = 0; k < spec.modes_per_cell(); ++k) want.insert(c);
    return have == want;
  } catch (const io::InputError&) {
    return false;  // unreadable or torn: run it again
  }
}

ShardLock::ShardLock(const fs::path& dir, int shard, int count) {
  std::string name = shard_file_name(shard, count);
  name.replace(name.size() - 4, 4, ".lock");
  const fs::path path = dir / name;
  fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0) throw io::InputError(path.string() + ": cannot open: " + std::strerror(errno));
  // A POSIX record lock on the whole (empty) file: the kernel releases it however the
  // process ends, F_GETLK names its holder, and it works over NFS, where Slurm's shards
  // often write.
  struct flock lock {};
  lock.l_type = F_WRLCK;
  lock.l_whence = SEEK_SET;
  if (::fcntl(fd_, F_SETLK, &lock) != 0) {
    // EACCES or EAGAIN: another process holds it; anything else (ENOLCK: an NFS mount
    // without its lock daemon) is said as it is.
    if (errno != EACCES && errno != EAGAIN) {
      const std::string why = std::strerror(errno);
      ::close(fd_);
      fd_ = -1;
      throw io::InputError(path.string() + ": cannot lock: " + why);
    }
    struct flock held {};
    held.l_type = F_WRLCK;
    held.l_whence = SEEK_SET;
    const bool named = ::fcntl(fd_, F_GETLK, &held) == 0 && held.l_type != F_UNLCK;
    ::close(fd_);
    fd_ = -1;
    throw io::InputError(path.string() + ": shard " + std::to_string(shard) + "/" +
                         std::to_string(count) + " is being run by another process" +
                         (named ? " (pid " + std::to_string(held.l_pid) + ")" : std::string()) +
                         "; wait for it, or run another shard");
  }
}

ShardLock::~ShardLock() {
  if (fd_ >= 0) ::close(fd_);  // releases the lock
}

fs::path cell_records_dir(const fs::path& dir, int shard, int count) {
  std::string name = shard_file_name(shard, count);
  name.replace(name.size() - 4, 4, ".cells");
  return dir / name;
}

void write_cell_record(const fs::path& dir, const SweepSpec& spec, int shard, int count,
                       std::size_t cell, const std::vector<SweepRow>& rows) {
  const fs::path records = cell_records_dir(dir, shard, count);
  std::error_code ec;
  fs::create_directories(records, ec);
  if (ec) throw io::InputError(records.string() + ": cannot create: " + ec.message());
  io::write_file_atomic(records / (std::to_string(cell) + ".csv"), [&](std::ostream& os) {
    os << csv_line(shard_columns(spec));
    const std::string digest = sweep_digest(spec);
    for (const SweepRow& r : rows) write_row(os, r, digest);
  });
}

std::optional<std::vector<SweepRow>> read_cell_record(const fs::path& dir, const SweepSpec& spec,
                                                      int shard, int count, std::size_t cell) {
  const fs::path path = cell_records_dir(dir, shard, count) / (std::to_string(cell) + ".csv");
  if (!fs::exists(path)) return std::nullopt;
  try {
    const io::CsvTable f = io::read_csv(path, shard_limits(spec, 1));
    if (f.header != shard_columns(spec) || f.rows.size() != spec.modes_per_cell())
      return std::nullopt;
    const std::size_t n_det = sweep_columns(spec).size();
    const std::string digest = sweep_digest(spec);
    std::vector<SweepRow> rows;
    for (std::size_t i = 0; i < f.rows.size(); ++i) {
      const std::vector<std::string>& row = f.rows[i];
      check_shard_row(spec, digest, f.header, row, path, f.lines[i]);
      if (parse_index(row[0], path) != cell) return std::nullopt;
      SweepRow r;
      r.cell = cell;
      r.mode = i;
      r.values.assign(row.begin(), row.begin() + static_cast<long>(n_det));
      r.timing = {row[0], row[1]};
      r.timing.insert(r.timing.end(), row.begin() + static_cast<long>(n_det), row.end() - 1);
      rows.push_back(std::move(r));
    }
    return rows;
  } catch (const io::InputError&) {
    return std::nullopt;  // torn or foreign: the cell runs again
  }
}

MergeResult merge_sweep(const fs::path& dir) {
  const SweepSpec spec = read_manifest(dir);
  // The manifest's own: the merge needs no scene file, and a shard must be of this sweep
  // as it began.
  const std::string digest = stored_digest(dir);
  const std::vector<std::string> header = shard_columns(spec);
  const std::size_t n_det = sweep_columns(spec).size();
  const std::size_t per_cell = spec.modes_per_cell();
  std::vector<std::vector<std::vector<std::string>>> by_cell(spec.cells());
  MergeResult result;
  std::vector<fs::path> files;
  std::size_t rows_read = 0;
  for (const auto& entry : fs::directory_iterator(dir))
    if (is_shard_file_name(entry.path().filename().string())) files.push_back(entry.path());
  std::sort(files.begin(), files.end());
  for (const fs::path& path : files) {
    const io::CsvTable f = io::read_csv(path, shard_limits(spec, spec.cells()));
    if (f.header != header)
      throw io::InputError(path.string() + ": its columns differ from " +
                           (dir / kManifest).string() + "'s sweep");
    for (std::size_t i = 0; i < f.rows.size(); ++i) {
      check_shard_row(spec, digest, header, f.rows[i], path, f.lines[i]);
      std::vector<std::string>& row =
          by_cell[parse_index(f.rows[i][0], path)].emplace_back(f.rows[i]);
      row.pop_back();  // the digest: not in the merged tables
    }
    ++result.shard_files;
    // All the shard files together hold the grid's rows once; doubled shards are named
    // below, but copies without end are refused here, before they are all held.
    rows_read += f.rows.size();
    if (rows_read > io::rows_with_room(spec.cells() * per_cell))
      throw io::InputError("sweep merge " + dir.string() + ": the shard files up to " +
                           path.filename().string() + " hold " + std::to_string(rows_read) +
                           " rows, where the grid has " + std::to_string(spec.cells() * per_cell) +
                           " (shards copied in more than once?)");
    if (fs::exists(failed_file(path))) {
      io::CsvLimits failed_limits;  // a row per failed cell: cell,error,sweep_digest
      failed_limits.max_rows = spec.cells();
      failed_limits.max_columns = 3;
      const io::CsvTable failed = io::read_csv(failed_file(path), failed_limits);
      if (failed.header != std::vector<std::string>{"cell", "error", kDigestColumn})
        throw io::InputError(failed_file(path).string() + ":1: expected the columns cell,error," +
                             kDigestColumn);
      for (std::size_t i = 0; i < failed.rows.size(); ++i) {
        const std::vector<std::string>& row = failed.rows[i];
        const std::string at = failed_file(path).string() + ":" + std::to_string(failed.lines[i]);
        const std::size_t cell = parse_index(row[0], failed_file(path));
        if (cell >= spec.cells())
          throw io::InputError(at + ": cell " + io::echo(row[0]) + " is beyond the grid's " +
                               std::to_string(spec.cells()) + " cells");
        if (row[2] != digest)
          throw io::InputError(at + ": its sweep digest is '" + io::echo(row[2]) +
                               "', this sweep's is '" + digest + "' (a shard of another sweep)");
        result.failed.push_back({cell, row[1]});
      }
    }
  }
  std::sort(result.failed.begin(), result.failed.end(),
            [](const SweepFailure& a, const SweepFailure& b) { return a.cell < b.cell; });
  std::vector<bool> failed(spec.cells(), false);
  for (const SweepFailure& f : result.failed) failed[f.cell] = true;
  std::vector<std::size_t> missing, doubled;
  for (std::size_t c = 0; c < by_cell.size(); ++c) {
    auto& rows = by_cell[c];
    if (failed[c] && rows.empty()) continue;  // listed in cells_failed.csv
    std::set<std::string> modes;
    for (const auto& r : rows) modes.insert(r[1]);
    if (rows.size() > per_cell || modes.size() != rows.size()) {
      doubled.push_back(c);
    } else if (rows.size() < per_cell) {
      missing.push_back(c);
    }
  }
  if (!missing.empty() || !doubled.empty()) {
    std::string msg = "sweep merge " + dir.string() + ": ";
    if (!missing.empty())
      msg += std::to_string(missing.size()) + " of " + std::to_string(spec.cells()) +
             " cells missing (" + ranges(missing) + ")";
    if (!doubled.empty())
      msg += std::string(missing.empty() ? "" : "; ") + std::to_string(doubled.size()) +
             " cells doubled (" + ranges(doubled) + ")";
    msg += "; shard files read: " + std::to_string(files.size());
    throw io::InputError(msg);
  }
  // Rows of a cell in the order of the manifest's modes (or its one mode), then its
  // external trackers.
  std::vector<std::string> mode_order;
  for (const TrackerMode m : spec.modes) mode_order.emplace_back(to_string(m));
  for (const ExternalTrackerSpec& e : spec.external) mode_order.push_back(e.name);
  io::StagedFiles out;
  if (!result.failed.empty()) {
    std::ostream& f = out.open(dir / "cells_failed.csv");
    f << "cell,error\n";
    for (const SweepFailure& x : result.failed) f << x.cell << ',' << one_field(x.error) << '\n';
  } else {
    std::error_code ec;
    fs::remove(dir / "cells_failed.csv", ec);
  }
  std::ostream& cells = out.open(dir / "cells.csv");
  std::ostream& timing = out.open(dir / "cells_timing.csv");
  cells << csv_line(sweep_columns(spec));
  timing << csv_line(sweep_timing_columns());
  for (auto& rows : by_cell) {
    if (!mode_order.empty()) {
      // A name not in the manifest's list (the scene's own mode) first.
      const auto rank = [&](const std::string& name) {
        const auto it = std::find(mode_order.begin(), mode_order.end(), name);
        return it == mode_order.end() ? -1 : static_cast<long>(it - mode_order.begin());
      };
      std::sort(rows.begin(), rows.end(),
                [&](const auto& a, const auto& b) { return rank(a[1]) < rank(b[1]); });
    }
    for (const auto& r : rows) {
      cells << csv_line({r.begin(), r.begin() + static_cast<long>(n_det)});
      std::vector<std::string> t = {r[0], r[1]};
      t.insert(t.end(), r.begin() + static_cast<long>(n_det), r.end());
      timing << csv_line(t);
      ++result.rows;
    }
  }
  out.commit();
  result.cells = spec.cells();
  return result;
}

}  // namespace linksight::sim
