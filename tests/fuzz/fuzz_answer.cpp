// An external tracker's answer line (docs/protocol.md): never throws; nodes are given
// only for a well-formed answer, then the asked count of finite nodes within 100 m; a lost
// answer's reason is one printable line.
#include <cmath>

#include "fuzz_support.hpp"
#include "linksight/sim/external_tracker.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace linksight;
  const std::string line(reinterpret_cast<const char*>(data), size);
  try {
    const sim::ExternalAnswer a = sim::parse_external_answer(line, 3, 12);
    if (a.lost.empty()) {
      if (a.nodes.size() != 12) fuzz::finding("an answer taken with the wrong node count");
      for (const auto& q : a.nodes)
        if (!q.allFinite() || q.cwiseAbs().maxCoeff() > 100.0)
          fuzz::finding("an answer taken with a node beyond 100 m or not finite");
    } else if (!a.nodes.empty()) {
      fuzz::finding("a lost answer with nodes");
    } else {
      fuzz::expect_printable(a.lost);
    }
  } catch (const std::exception& e) {
    fuzz::finding(std::string("parse_external_answer threw: ") + e.what());
  }
  return 0;
}
