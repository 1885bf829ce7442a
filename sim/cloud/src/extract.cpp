#include "linksight/sim/extract.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <numbers>
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

namespace {

// Whether the points `in` (within plane_threshold of the plane through `mean`, with
// orthonormal in-plane axes e1, e2) span `width` along both and occupy a square of 7 x 7
// cells of width / 5 on a grid along them (the usual dynamic programme over the cells).
bool occupies_square(const std::vector<Eigen::Vector3d>& in, const Eigen::Vector3d& mean,
                     const Eigen::Vector3d& e1, const Eigen::Vector3d& e2, double width) {
  double lo1 = 1e300, hi1 = -1e300, lo2 = 1e300, hi2 = -1e300;
  for (const Eigen::Vector3d& q : in) {
    const double a = e1.dot(q - mean), b = e2.dot(q - mean);
    lo1 = std::min(lo1, a), hi1 = std::max(hi1, a);
    lo2 = std::min(lo2, b), hi2 = std::max(hi2, b);
  }
  if (hi1 - lo1 < width || hi2 - lo2 < width) return false;
  // At most about 4 million cells: coarser cells only for a plane tens of metres wide.
  constexpr double kMaxCells = 4e6;
  const double cell = std::max(width / 5, std::sqrt((hi1 - lo1) * (hi2 - lo2) / kMaxCells));
  // Points in k cells in a row span more than k - 2 cells: k = 7 for cells of width / 5.
  const int side = static_cast<int>(std::ceil(width / cell - 1e-9)) + 2;
  const int n1 = static_cast<int>((hi1 - lo1) / cell) + 1;
  const int n2 = static_cast<int>((hi2 - lo2) / cell) + 1;
  std::vector<int> run(static_cast<std::size_t>(n1) * n2, 0);  // occupied first, then the DP
  for (const Eigen::Vector3d& q : in) {
    const int i = std::min(n1 - 1, static_cast<int>((e1.dot(q - mean) - lo1) / cell));
    const int j = std::min(n2 - 1, static_cast<int>((e2.dot(q - mean) - lo2) / cell));
    run[static_cast<std::size_t>(j) * n1 + i] = 1;
  }
  for (int j = 1; j < n2; ++j)
    for (int i = 1; i < n1; ++i) {
      int& r = run[static_cast<std::size_t>(j) * n1 + i];
      if (r == 0) continue;
      r = 1 + std::min({run[static_cast<std::size_t>(j - 1) * n1 + i],
                        run[static_cast<std::size_t>(j) * n1 + i - 1],
                        run[static_cast<std::size_t>(j - 1) * n1 + i - 1]});
      if (r >= side) return true;
    }
  return false;
}

// Whether the points `in` are wider than `width` both ways: they occupy 7 x 7 cells of a
// fifth of it on a grid along e1, e2 (their principal axes) or turned by 30 or 60 degrees
// in the plane. That takes more than `width` both ways. The principal axes of a square or
// a disc fall anywhere, so one grid would refuse a square 1.7 widths wide at 45 degrees to
// it; with three, any square over 1.5 widths and any disc over 1.7 widths across passes
// (given a point every few millimetres). A table or a wall does; a row of balls (a strip a
// ball wide, bent or not), or such a row and a small object in the same plane, does not.
bool wide_both_ways(const std::vector<Eigen::Vector3d>& in, const Eigen::Vector3d& mean,
                    const Eigen::Vector3d& e1, const Eigen::Vector3d& e2, double width) {
  for (const double deg : {0.0, 30.0, 60.0}) {
    const double t = deg * std::numbers::pi / 180;
    const Eigen::Vector3d a = std::cos(t) * e1 + std::sin(t) * e2;
    const Eigen::Vector3d b = -std::sin(t) * e1 + std::cos(t) * e2;
    if (occupies_square(in, mean, a, b, width)) return true;
  }
  return false;
}

}  // namespace

Cloud remove_planes(const Cloud& cloud, const ExtractParams& params, std::uint64_t seed) {
  params.validate();
  const std::size_t total = cloud.size();
  std::vector<std::size_t> keep(total);
  for (std::size_t i = 0; i < total; ++i) keep[i] = i;
  // The points hypotheses are drawn from: `keep` less the inliers of planes refused for
  // their width, which stay in the cloud.
  std::vector<std::size_t> candidates = keep;
  auto point = [&](std::size_t i) {
    return Eigen::Vector3d(cloud.xyz[3 * i], cloud.xyz[3 * i + 1], cloud.xyz[3 * i + 2]);
  };
  std::uint64_t state = derive_seed(seed, "ransac");
  const double min_inliers = params.min_plane_fraction * static_cast<double>(total);
  // A refused plane says nothing of a wider one with fewer points (the best plane can be
  // the link), so the search goes on past it; each refusal takes at least min_inliers
  // points out of the candidates, so it ends.
  int removed = 0;
  while (removed < params.max_planes && candidates.size() >= 3) {
    // Hypotheses are scored on a fixed-size random subset; the winner on all points.
    const std::size_t m = std::min<std::size_t>(candidates.size(), 4000);
    std::vector<std::size_t> subset(m);
    for (std::size_t i = 0; i < m; ++i)
      subset[i] = candidates[static_cast<std::size_t>(unit_draw(state) * candidates.size())];
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
    std::vector<Eigen::Vector3d> in;
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (std::size_t i : candidates) {
      const Eigen::Vector3d q = point(i);
      if (std::abs(best_n.dot(q) + best_d) < params.plane_threshold) {
        mean += q;
        in.push_back(q);
      }
    }
    if (in.size() < 3 || static_cast<double>(in.size()) < min_inliers) break;
    mean /= static_cast<double>(in.size());
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const Eigen::Vector3d& q : in) cov += (q - mean) * (q - mean).transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
    const Eigen::Vector3d n = eig.eigenvectors().col(0);  // eigenvalues ascending
    const auto on_plane = [&](std::size_t i) {
      return std::abs(n.dot(point(i) - mean)) < params.plane_threshold;
    };
    std::vector<std::size_t> rest;
    if (params.min_plane_width > 0 &&
        !wide_both_ways(in, mean, eig.eigenvectors().col(1), eig.eigenvectors().col(2),
                       params.min_plane_width)) {
      for (std::size_t i : candidates)
        if (!(std::abs(best_n.dot(point(i)) + best_d) < params.plane_threshold)) rest.push_back(i);
      candidates.swap(rest);
      continue;
    }
    ++removed;
    for (std::size_t i : keep)
      if (!on_plane(i)) rest.push_back(i);
    keep.swap(rest);
    rest.clear();
    for (std::size_t i : candidates)
      if (!on_plane(i)) rest.push_back(i);
    candidates.swap(rest);
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
