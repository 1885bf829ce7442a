#include "linksight/io/atomic_file.hpp"

#include <unistd.h>
#include <atomic>
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

}  // namespace linksight::io
