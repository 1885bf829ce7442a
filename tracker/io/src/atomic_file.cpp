#include "linksight/io/atomic_file.hpp"

#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <charconv>
#include <string_view>
#include <fstream>
#include <system_error>

#include "linksight/io/error.hpp"

namespace linksight::io {
namespace fs = std::filesystem;
namespace {
// Unique within the process and across processes writing the same directory.
fs::path temp_name(const fs::path& final_path) {
  static std::atomic<unsigned> counter{0};
  fs::path tmp = final_path;
  tmp += ".tmp." + std::to_string(::getpid()) + "." + std::to_string(counter++);
  return tmp;
}
}  // namespace

struct StagedFiles::Entry {
  fs::path final_path, temp_path;
  std::ofstream stream;
  bool done = false;
};

std::ostream& StagedFiles::open(const fs::path& final_path, bool binary) {
  auto e = std::make_unique<Entry>();
  e->final_path = final_path;
  e->temp_path = temp_name(final_path);
  e->stream.open(e->temp_path, binary ? std::ios::binary | std::ios::out : std::ios::out);
  if (!e->stream) throw InputError(final_path.string() + ": cannot open for writing");
  entries_.push_back(std::move(e));
  return entries_.back()->stream;
}

void StagedFiles::commit() {
  for (auto& e : entries_) {
    e->stream.close();
    if (!e->stream) throw InputError(e->final_path.string() + ": write failed");
  }
  for (auto& e : entries_) {
    std::error_code ec;
    fs::rename(e->temp_path, e->final_path, ec);
    if (ec)
      throw InputError(e->final_path.string() + ": cannot rename into place: " + ec.message());
    e->done = true;
  }
}

StagedFiles::StagedFiles() = default;

StagedFiles::~StagedFiles() {
  for (auto& e : entries_) {
    if (e->done) continue;
    e->stream.close();
    std::error_code ec;
    fs::remove(e->temp_path, ec);
  }
}

void write_file_atomic(const fs::path& path, const std::function<void(std::ostream&)>& write,
                       bool binary) {
  StagedFiles staged;
  write(staged.open(path, binary));
  staged.commit();
}

namespace {
// The process id in `name` when it is `stem` + `tag` + digits (not this process's); else 0.
long pid_in(const std::string& name, const std::string& stem, std::string_view tag) {
  const std::string head = stem + std::string(tag);
  if (name.size() <= head.size() || name.compare(0, head.size(), head) != 0) return 0;
  const char* first = name.data() + head.size();
  const char* last = name.data() + name.size();
  long pid = 0;
  const auto r = std::from_chars(first, last, pid);
  if (r.ec != std::errc() || r.ptr != last || pid <= 0 || pid == ::getpid()) return 0;
  return pid;
}

// Whether process `pid` has ended (gone, or a zombie nobody reaped yet).
bool ended(long pid) {
  if (::kill(static_cast<pid_t>(pid), 0) != 0) return errno == ESRCH;
  // A killed process whose parent is gone too may linger as a zombie until init reaps it.
  std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
  std::string line;
  std::getline(stat, line);
  const std::size_t paren = line.rfind(')');
  return paren != std::string::npos && paren + 2 < line.size() && line[paren + 2] == 'Z';
}
}  // namespace

StagedDir::StagedDir(fs::path dir, bool force) : dir_(std::move(dir)), force_(force) {
  std::error_code ec;
  const fs::file_status st = fs::symlink_status(dir_, ec);
  if (fs::exists(st) && !fs::is_directory(st))
    throw InputError(dir_.string() + ": exists and is not a directory (an output directory is " +
                     "replaced with --force, never a file)");
  if (fs::exists(st) && !force)
    throw InputError(dir_.string() + ": output directory exists (use --force to replace it)");
  const fs::path parent = dir_.has_parent_path() ? dir_.parent_path() : fs::path(".");
  fs::create_directories(parent, ec);
  if (ec) throw InputError(parent.string() + ": cannot create directory: " + ec.message());
  // Staging and replaced directories of runs into the same DIR that were killed: gone now.
  // A live run's staging means another process is writing DIR: refused, naming it.
  const std::string stem = dir_.filename().string();
  for (fs::directory_iterator it(parent, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    const long staging = pid_in(name, stem, ".partial-"), old = pid_in(name, stem, ".old-");
    if ((staging != 0 && ended(staging)) || (old != 0 && ended(old))) {
      std::error_code rm;
      fs::remove_all(it->path(), rm);
    } else if (staging != 0) {
      throw InputError(dir_.string() + ": another process (pid " + std::to_string(staging) +
                       ") is writing this output directory now (" + it->path().string() +
                       "); wait for it, or give another --out");
    }
  }
  ec.clear();
  staging_ = parent / (dir_.filename().string() + ".partial-" + std::to_string(::getpid()));
  fs::remove_all(staging_, ec);
  fs::create_directories(staging_, ec);
  if (ec) throw InputError(dir_.string() + ": cannot create output directory: " + ec.message());
}

StagedDir::~StagedDir() {
  if (committed_) return;
  std::error_code ec;
  fs::remove_all(staging_, ec);
}

void StagedDir::commit() {
  std::error_code ec;
  fs::path old;
  // DIR appeared while this run wrote (another run into the same --out that started at
  // the same instant): without --force it is not replaced.
  if (!force_ && fs::exists(dir_, ec))
    throw InputError(dir_.string() + ": written by another process while this run was " +
                     "writing it; this run's output is dropped (use --force to replace)");
  if (fs::exists(dir_, ec)) {
    old = dir_.string() + ".old-" + std::to_string(::getpid());
    fs::rename(dir_, old, ec);
    if (ec) throw InputError(dir_.string() + ": cannot replace: " + ec.message());
  }
  fs::rename(staging_, dir_, ec);
  if (ec) throw InputError(dir_.string() + ": cannot finish: " + ec.message());
  committed_ = true;
  if (!old.empty()) fs::remove_all(old, ec);
}

}  // namespace linksight::io
