#pragma once
/// @file Write-to-temp-then-rename, so a failed run never leaves a partial file.

#include <filesystem>
#include <functional>
#include <iosfwd>
#include <memory>
#include <vector>

namespace linksight::io {

/// Writes `path` atomically: `write` fills a temporary file in the same directory,
/// which is renamed over `path` only if `write` returns normally. Throws InputError
/// naming the path when the file cannot be written.
void write_file_atomic(const std::filesystem::path& path,
                       const std::function<void(std::ostream&)>& write, bool binary = false);

/// Several output files that appear together or not at all: each is staged to a
/// temporary name; commit() renames them all; the destructor removes what was not
/// committed.
class StagedFiles {
 public:
  StagedFiles();
  StagedFiles(const StagedFiles&) = delete;
  StagedFiles& operator=(const StagedFiles&) = delete;
  ~StagedFiles();
  /// Opens a temporary file for `final_path`; the stream stays valid until commit().
  std::ostream& open(const std::filesystem::path& final_path, bool binary = false);
  void commit();

 private:
  struct Entry;
  std::vector<std::unique_ptr<Entry>> entries_;
};

/// An output directory that appears whole or not at all: files go into a staging
/// directory `DIR.partial-PID` beside it; commit() renames it to DIR (replacing an old DIR
/// only when `force`); the destructor removes an uncommitted staging directory.
/// Construction removes the staging directories of runs into DIR whose process has ended
/// (killed), and refuses, naming its pid, while another live process stages DIR.
/// Throws InputError naming DIR when it exists and !force, is a file, or cannot be created.
class StagedDir {
 public:
  StagedDir(std::filesystem::path dir, bool force);
  StagedDir(const StagedDir&) = delete;
  StagedDir& operator=(const StagedDir&) = delete;
  ~StagedDir();
  /// Where to write now (the staging directory).
  [[nodiscard]] const std::filesystem::path& path() const { return staging_; }
  [[nodiscard]] const std::filesystem::path& final_path() const { return dir_; }
  void commit();

 private:
  std::filesystem::path dir_, staging_;
  bool force_ = false;
  bool committed_ = false;
};

}  // namespace linksight::io
