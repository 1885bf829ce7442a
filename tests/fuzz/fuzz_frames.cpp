// Frame lists: a FILE, DIR or GLOB given as --input, expanded in a folder of a few frames.
// Every path listed exists and is a frame; anything else is an InputError naming the input
// or the file in it that is not a frame (a glob's match).
#include <filesystem>

#include "fuzz_support.hpp"
#include "linksight/io/frames.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace linksight;
  namespace fs = std::filesystem;
  static const fs::path dir = [] {
    const fs::path d = fuzz::scratch() / "frames";
    fs::create_directories(d / "sub");
    for (const char* f : {"f2.ply", "f10.ply", "a.png", "notes.txt", "sub/f1.ply"})
      std::ofstream(d / f) << "x";
    return d;
  }();
  std::string pattern(reinterpret_cast<const char*>(data), size);
  if (pattern.find('\0') != std::string::npos) return 0;  // not a path a shell can pass
  // A pattern that climbs out of the folder globs the host's whole file system (a
  // "../../*/*/*" walk is slow, not wrong; glob's ".*" matches ".." too): the fuzzer stays
  // inside the folder, so no component may start with '.', escaped ("\\.") or not.
  std::string plain;
  for (const char c : pattern)
    if (c != '\\') plain += c;
  if (plain.rfind('.', 0) == 0 || plain.find("/.") != std::string::npos) return 0;
  // Joined as text: a path join would drop the folder for a pattern starting with '/'
  // (the harness's own mistake, found by the fuzzer), and the input starts with the folder.
  const std::string input = dir.string() + "/" + pattern;
  fuzz::expect_named(dir.string(), [&] {
    for (const fs::path& p : io::list_frames(input)) {
      if (!fs::is_regular_file(p)) fuzz::finding("listed " + p.string() + ", not a file");
      const std::string e = p.extension().string();
      if (e != ".ply" && e != ".png") fuzz::finding("listed " + p.string() + ", not a frame");
    }
  });
  return 0;
}
