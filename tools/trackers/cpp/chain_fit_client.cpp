// chain-fit as an external tracker (docs/protocol.md, version 1): reads each frame's
// header and cloud from stdin, runs linksight::Tracker in mode chain-fit on it (with the
// base pose when the header gives one) and answers the nodes on stdout.
#include <cstdint>
#include <cstdio>
#include <optional>
#include <cstdlib>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include <linksight/tracker/tracker.hpp>

int main() {
  linksight::TrackerParams params;
  params.mode = linksight::parse_mode("chain-fit");
  params.compute_sdf = false;  // the harness scores
  std::optional<linksight::Tracker> tracker;
  char* line = nullptr;
  std::size_t cap = 0;
  while (getline(&line, &cap, stdin) > 0) {
    const nlohmann::json h = nlohmann::json::parse(line);
    if (h.at("linksight").get<int>() != 1) {
      std::fprintf(stderr, "chain_fit_client: protocol version %s, expected 1\n",
                   h.at("linksight").dump().c_str());
      return 2;
    }
    if (!tracker) {
      // The first frame says what the link is.
      const nlohmann::json& c = h.at("chain");
      params.geometry.ball_radius = c.at("ball_radius_m");
      params.geometry.pitch = c.at("pitch_m");
      params.geometry.neck_radius = c.at("neck_radius_m");
      params.geometry.neck_length = c.at("neck_length_m");
      params.geometry.count = c.at("count");
      params.nodes = h.at("nodes");
      params.policy.lsq_init.pitch = params.geometry.pitch;
      if (h.contains("base_pose")) {
        params.base_prior.enabled = true;
        params.base_prior.sigma_m = h["base_pose"].at("sigma_m");
        params.base_prior.sigma_rad = h["base_pose"].at("sigma_deg").get<double>() * M_PI / 180.0;
      }
      tracker.emplace(params);
    }
    const std::size_t n = h.at("points");
    linksight::Cloud cloud;
    cloud.xyz.resize(3 * n);
    if (std::fread(cloud.xyz.data(), 12, n, stdin) != n) return 0;  // the episode ended
    if (h.contains("depth")) {  // scene key external.send_depth: not used here
      std::vector<std::uint16_t> depth(h["depth"].at("width").get<std::size_t>() *
                                       h["depth"].at("height").get<std::size_t>());
      if (std::fread(depth.data(), 2, depth.size(), stdin) != depth.size()) return 0;
    }
    Eigen::Isometry3d X_CB;
    const bool pose = h.contains("base_pose");
    if (pose)
      for (int i = 0; i < 16; ++i) X_CB.matrix()(i / 4, i % 4) = h["base_pose"]["X_CB"][i];
    const linksight::FrameResult r = tracker->step(cloud, pose ? &X_CB : nullptr);
    nlohmann::json a = {{"frame", h.at("frame")}};
    if (r.lost) {
      a["lost"] = true;
      a["reason"] = std::string(linksight::to_string(r.lost_reason));
    } else {
      a["nodes"] = nlohmann::json::array();
      for (const Eigen::Vector3d& q : r.nodes) a["nodes"].push_back({q.x(), q.y(), q.z()});
      a["reinit"] = r.reinit;
    }
    std::printf("%s\n", a.dump().c_str());
    std::fflush(stdout);
  }
  std::free(line);
  return 0;
}
