#pragma once
// One fuzz target per reader of outside bytes (issue 19, part 1). Each defines
// LLVMFuzzerTestOneInput and asserts the contract, not only "no crash": the reader either
// returns a result that passes its checks, or throws the project's io::InputError with a
// message that names the input and prints as one line. Anything else (another exception, a message
// that does not name the file, a result that breaks its own invariants) aborts, which libFuzzer and
// the corpus replay (replay_main.cpp) report as a finding.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

#include "linksight/io/error.hpp"

namespace linksight::fuzz {

/// A scratch directory of this process, made once and removed at exit (readers take
/// files, not buffers).
inline const std::filesystem::path& scratch() {
  struct Dir {
    std::filesystem::path path;
    Dir() {
      const char* tmp = std::getenv("TMPDIR");
      path = std::filesystem::path(tmp != nullptr && *tmp ? tmp : "/tmp") /
             ("linksight_fuzz_" + std::to_string(::getpid()));
      std::filesystem::create_directories(path);
    }
    ~Dir() {
      std::error_code ec;
      std::filesystem::remove_all(path, ec);
    }
  };
  static const Dir dir;
  return dir.path;
}

/// Writes `data` to scratch()/name and returns its path.
inline std::filesystem::path write_input(const std::string& name, const std::uint8_t* data,
                                         std::size_t size) {
  const std::filesystem::path p = scratch() / name;
  std::ofstream(p, std::ios::binary | std::ios::trunc)
      .write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  return p;
}

[[noreturn]] inline void finding(const std::string& what) {
  std::fprintf(stderr, "linksight fuzz: contract broken: %s\n", what.c_str());
  std::abort();
}

/// A refusal must print as one line of bounded length with no control byte
/// (io::printable_line, docs/reliability.md "Echoing input").
inline void expect_printable(std::string_view message) {
  if (!io::is_printable_line(message))
    finding("a message that is not one printable line: " + io::printable_line(message));
}

/// Runs `read`; an io::InputError must name `input`, any other exception is a finding.
template <class F>
void expect_named(const std::string& input, F&& read) {
  try {
    read();
  } catch (const io::InputError& e) {
    const std::string_view what = e.what();
    if (what.find(input) == std::string_view::npos)
      finding("an error that does not name " + input + ": " + std::string(what));
    expect_printable(what);
  } catch (const std::exception& e) {
    finding(std::string("not io::InputError: ") + typeid(e).name() + ": " + e.what());
  }
}

}  // namespace linksight::fuzz
