#include "linksight/sim/extract.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

#include "linksight/tracker/seed.hpp"

namespace linksight::sim {
namespace {

double unit_draw(std::uint64_t& state) {
  return unit_interval(splitmix64(state));
}

}  // namespace

void ExtractParams::validate() const {
  fields::check(*this, "segmentation");
  if (!(max_depth > min_depth))
    fields::fail("segmentation", "max_depth_m", max_depth,
                 "must be > min_depth_m (" + format_shortest(min_depth) + ")");
  if (crop_C && crop_C->isEmpty())
    throw fields::FieldError("crop_max_m", "[...]", "the crop box is empty", "segmentation");
}

std::string_view to_string(ExtractMode mode) { return mode == ExtractMode::truth ? "truth" : "depth"; }

ExtractMode parse_extract_mode(std::string_view name) {
  if (name == "truth") return ExtractMode::truth;
  if (name == "depth") return ExtractMode::depth;
  throw std::invalid_argument("unknown segmentation mode '" + std::string(name) +
                              "' (expected truth or depth)");
}

Cloud remove_planes(const Cloud& cloud, const ExtractParams& params, std::uint64_t seed) {
  params.validate();
  const std::size_t total = cloud.size();
  std::vector<std::size_t> keep(total);
  for (std::size_t i = 0; i < total; ++i) keep[i] = i;
  auto point = [&](std::size_t i) {
    return Eigen::Vector3d(cloud.xyz[3 * i], cloud.xyz[3 * i + 1], cloud.xyz[3 * i + 2]);
  };
  std::uint64_t state = derive_seed(seed, "ransac");
  const double min_inliers = params.min_plane_fraction * static_cast<double>(total);
  for (int plane = 0; plane < params.max_planes && keep.size() >= 3; ++plane) {
    // Hypotheses are scored on a fixed-size random subset; the winner on all points.
    const std::size_t m = std::min<std::size_t>(keep.size(), 4000);
    std::vector<std::size_t> subset(m);
    for (std::size_t i = 0; i < m; ++i)
      subset[i] = keep[static_cast<std::size_t>(unit_draw(state) * keep.size())];
    Eigen::Vector3d best_n = Eigen::Vector3d::UnitZ();
    double best_d = 0;
    long best_count = -1;
    for (int it = 0; it < params.ransac_iterations; ++it) {
      const Eigen::Vector3d a = point(subset[static_cast<std::size_t>(unit_draw(state) * m)]);
      const Eigen::Vector3d b = point(subset[static_cast<std::size_t>(unit_draw(state) * m)]);
      const Eigen::Vector3d c = point(subset[static_cast<std::size_t>(unit_draw(state) * m)]);
      Eigen::Vector3d nrm = (b - a).cross(c - a);
      if (!(nrm.norm() > 1e-12)) continue;
      nrm.normalize();
      const double d = -nrm.dot(a);
      long count = 0;
      for (std::size_t i : subset) count += std::abs(nrm.dot(point(i)) + d) < params.plane_threshold;
      if (count > best_count) {
        best_count = count;
        best_n = nrm;
        best_d = d;
      }
    }
    // Refit to the inliers (least squares), then split once more.
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    long n_in = 0;
    for (std::size_t i : keep) {
      if (std::abs(best_n.dot(point(i)) + best_d) < params.plane_threshold) {
        mean += point(i);
        ++n_in;
      }
    }
    if (n_in < 3 || static_cast<double>(n_in) < min_inliers) break;
    mean /= static_cast<double>(n_in);
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (std::size_t i : keep) {
      const Eigen::Vector3d q = point(i);
      if (std::abs(best_n.dot(q) + best_d) < params.plane_threshold)
        cov += (q - mean) * (q - mean).transpose();
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
    // Eigenvalues ascending: the normal's, then the narrower in-plane direction's. A uniform
    // strip of width w has variance w^2 / 12 across it.
    const double width = std::sqrt(12 * std::max(eig.eigenvalues()(1), 0.0) / static_cast<double>(n_in));
    if (width < params.min_plane_width) break;
    const Eigen::Vector3d n = eig.eigenvectors().col(0);
    std::vector<std::size_t> rest;
    rest.reserve(keep.size());
    for (std::size_t i : keep)
      if (!(std::abs(n.dot(point(i) - mean)) < params.plane_threshold)) rest.push_back(i);
    keep.swap(rest);
  }
  Cloud out;
  out.xyz.reserve(3 * keep.size());
  for (std::size_t i : keep) out.push_back(cloud.xyz[3 * i], cloud.xyz[3 * i + 1], cloud.xyz[3 * i + 2]);
  return out;
}

Cloud extract_cloud(const DepthFrame& frame, const io::Intrinsics& K, int count,
                    const ExtractParams& params, std::uint64_t seed, std::uint64_t frame_index) {
  params.validate();
  io::DepthToCloudOptions range;
  range.min_depth = params.min_depth;
  range.max_depth = params.max_depth;
  const std::uint64_t frame_seed = derive_seed(derive_seed(seed, "extract"), frame_index);
  if (params.mode == ExtractParams::Mode::depth) {
    range.crop_C = params.crop_C;
    return remove_planes(io::depth_to_cloud(frame.depth, K, range), params, frame_seed);
  }
  const int W = frame.width, H = frame.height;
  const std::size_t n = static_cast<std::size_t>(W) * H;
  io::DepthImage masked;
  masked.width = W;
  masked.height = H;
  masked.data.assign(n, 0);
  std::vector<std::uint8_t> near;  // within leakage_px of a link pixel
  if (params.leakage > 0) {
    const int k = params.leakage_px;
    std::vector<std::uint8_t> rows(n, 0);
    for (int v = 0; v < H; ++v) {
      for (int u = 0; u < W; ++u) {
        if (frame.label[static_cast<std::size_t>(v) * W + u] >= count) continue;
        for (int uu = std::max(0, u - k); uu <= std::min(W - 1, u + k); ++uu)
          rows[static_cast<std::size_t>(v) * W + uu] = 1;
      }
    }
    near.assign(n, 0);
    for (int v = 0; v < H; ++v) {
      for (int u = 0; u < W; ++u) {
        if (!rows[static_cast<std::size_t>(v) * W + u]) continue;
        for (int vv = std::max(0, v - k); vv <= std::min(H - 1, v + k); ++vv)
          near[static_cast<std::size_t>(vv) * W + u] = 1;
      }
    }
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (frame.depth.data[i] == 0) continue;
    bool keep = frame.label[i] < count;
    if (!keep && params.leakage > 0 && near[i]) {
      keep = unit_interval(mix64(derive_seed(frame_seed, i))) <
             params.leakage;
    }
    if (keep) masked.data[i] = frame.depth.data[i];
  }
  return io::depth_to_cloud(masked, K, range);
}

}  // namespace linksight::sim
