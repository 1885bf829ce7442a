// A sweep's files from outside: the first input byte chooses sweep.json (read_manifest)
// or a shard CSV merged against a fixed manifest (merge_sweep; "@digest@" in it stands for
// that sweep's digest). A merge either writes
// cells.csv or throws an InputError naming the sweep directory.
#include <filesystem>

#include "fuzz_support.hpp"
#include "linksight/sim/sweep.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace linksight;
  namespace fs = std::filesystem;
  if (size == 0) return 0;
  const fs::path dir = fuzz::scratch() / "sweep";
  fs::remove_all(dir);
  fs::create_directories(dir);
  if (data[0] % 2 == 0) {
    (void)fuzz::write_input("sweep/sweep.json", data + 1, size - 1);
    fuzz::expect_named(dir.string(), [&] {
      const sim::SweepSpec s = sim::read_manifest(dir);
      try {
        s.validate();
      } catch (const std::exception& e) {
        fuzz::finding(std::string("a manifest read that validate() refuses: ") + e.what());
      }
    });
    return 0;
  }
  sim::SweepSpec spec;
  spec.scene = "static.yaml";
  spec.axes = {sim::parse_axis("noise.scale=0,1"), sim::parse_axis("seed=1,2")};
  spec.modes = {parse_mode("paper"), parse_mode("chain-fit")};
  spec.frames = 2;
  sim::write_manifest(dir, spec);
  // Every "@digest@" in the input stands for this sweep's digest, which a fuzzer cannot
  // guess: rows past the digest check stay reachable (as a PNG fuzzer fixes up CRCs).
  std::string shard(reinterpret_cast<const char*>(data + 1), size - 1);
  const std::string digest = sim::sweep_digest(spec);
  for (std::size_t at = 0; (at = shard.find("@digest@", at)) != std::string::npos;)
    shard.replace(at, 8, digest);
  (void)fuzz::write_input("sweep/" + sim::shard_file_name(0, 1),
                          reinterpret_cast<const std::uint8_t*>(shard.data()), shard.size());
  fuzz::expect_named(dir.string(), [&] {
    const sim::MergeResult r = sim::merge_sweep(dir);
    if (r.cells != 4 || !fs::exists(dir / "cells.csv"))
      fuzz::finding("a merge that neither refused nor wrote the grid's cells");
  });
  return 0;
}
