// Uses the installed tracker: track a straight row of points, write and read a PLY.
#include <cstdio>
#include <filesystem>
#include <linksight/io/ply.hpp>
#include <linksight/tracker/tracker.hpp>

int main() {
  linksight::Cloud cloud;
  for (int i = 0; i < 2000; ++i) cloud.push_back(-0.25f + 0.00025f * i, 0.0f, 0.6f);
  const auto path = std::filesystem::temp_directory_path() / "linksight_consumer.ply";
  linksight::io::write_ply(path, cloud);
  const linksight::Cloud back = linksight::io::read_ply(path);
  std::filesystem::remove(path);
  linksight::TrackerParams params;
  params.backend = linksight::BackendKind::openmp;
  linksight::Tracker tracker(params);
  const linksight::FrameResult r = tracker.step(back);
  std::printf("nodes %zu lost %d first x %.3f last x %.3f\n", r.nodes.size(), int(r.lost),
              r.nodes.front().x(), r.nodes.back().x());
  return (!r.lost && r.nodes.size() == 12 && r.nodes.front().x() < r.nodes.back().x()) ? 0 : 1;
}
