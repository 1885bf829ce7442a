#include "linksight/sim/synthetic_chain.hpp"

#include <cmath>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>

#include "linksight/tracker/seed.hpp"

namespace linksight::sim {
namespace {

// std::mt19937_64's sequence is fixed by the standard; distributions are not, so the
// uniform and normal draws are written out here.
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : g_(seed) {}
  double uniform() { return unit_interval(g_()); }
  double normal() {
    const double u1 = uniform();
    return standard_normal(u1, uniform());
  }
  Eigen::Vector3d unit() {
    Eigen::Vector3d v(normal(), normal(), normal());
    const double n = v.norm();
    return n > 0 ? Eigen::Vector3d(v / n) : Eigen::Vector3d::UnitZ();
  }

 private:
  std::mt19937_64 g_;
};

// Does the segment from the camera (origin) to p pass through the ball (c, r)?
bool blocks(const Eigen::Vector3d& p, const Eigen::Vector3d& c, double r) {
  const double len = p.norm();
  const Eigen::Vector3d dir = p / len;
  const double t = std::clamp(c.dot(dir), 0.0, len);
  const double margin = 1e-6;
  return (c - t * dir).norm() < r - margin && t < len - margin;
}

}  // namespace

void SurfaceSampling::validate() const {
  if (samples_per_ball < 0)
    throw std::invalid_argument("SurfaceSampling.samples_per_ball must be >= 0");
  if (samples_per_neck < 0)
    throw std::invalid_argument("SurfaceSampling.samples_per_neck must be >= 0");
  if (!(noise_sigma >= 0 && std::isfinite(noise_sigma))) {
    throw std::invalid_argument("SurfaceSampling.noise_sigma = " + std::to_string(noise_sigma) +
                                ": must be >= 0");
  }
}

std::vector<double> shape_bends(ChainShape shape, int count, double bend) {
  std::vector<double> b(static_cast<std::size_t>(std::max(count - 1, 0)), 0.0);
  for (std::size_t k = 0; k < b.size(); ++k) {
    if (shape == ChainShape::c_shape) b[k] = bend;
    if (shape == ChainShape::s_shape) b[k] = (2 * k + 1 < b.size()) ? bend : -bend;
  }
  return b;
}

Nodes chain_nodes(const ComponentGeometry& g, const std::vector<double>& bends,
                  const Eigen::Isometry3d& X_CB) {
  g.validate();
  if (bends.size() + 1 != static_cast<std::size_t>(g.count)) {
    throw std::invalid_argument("chain_nodes: need count-1 = " + std::to_string(g.count - 1) +
                                " bends, got " + std::to_string(bends.size()));
  }
  Nodes nodes;
  Eigen::Vector3d c_B = Eigen::Vector3d::Zero();
  double heading = 0.0;
  for (int k = 0; k <= g.count; ++k) {
    nodes.push_back(X_CB * c_B);
    if (k > 0 && k < g.count) heading += bends[static_cast<std::size_t>(k - 1)];
    c_B += g.pitch * Eigen::Vector3d(std::cos(heading), std::sin(heading), 0.0);
  }
  return nodes;
}

Cloud sample_visible_surface(const Nodes& nodes, const ComponentGeometry& g,
                             const SurfaceSampling& s) {
  g.validate();
  s.validate();
  if (nodes.size() != static_cast<std::size_t>(g.count) + 1) {
    throw std::invalid_argument("sample_visible_surface: need count+1 nodes");
  }
  Rng rng(s.seed);
  std::vector<bool> hidden(static_cast<std::size_t>(g.count), false);
  for (int h : s.hidden) {
    if (h < 0 || h >= g.count) throw std::invalid_argument("SurfaceSampling.hidden: bad index");
    hidden[static_cast<std::size_t>(h)] = true;
  }
  auto occluded = [&](const Eigen::Vector3d& p) {
    for (int k = 0; k < g.count; ++k) {
      if (!hidden[static_cast<std::size_t>(k)] &&
          blocks(p, nodes[static_cast<std::size_t>(k)], g.ball_radius))
        return true;
    }
    return false;
  };
  // Ball surface covered by its own neck or by the previous component's neck/socket.
  auto inside_neck = [&](const Eigen::Vector3d& p, int k) {
    const Eigen::Vector3d& c = nodes[static_cast<std::size_t>(k)];
    const Eigen::Vector3d axis = (nodes[static_cast<std::size_t>(k) + 1] - c).normalized();
    const double t = std::clamp((p - c).dot(axis), 0.0, g.neck_length);
    return (p - c - t * axis).norm() < g.neck_radius;
  };
  Cloud cloud;
  auto emit = [&](const Eigen::Vector3d& p, double noise) {
    cloud.push_back(Eigen::Vector3d(p + noise * p.normalized()));
  };
  for (int k = 0; k < g.count; ++k) {
    const Eigen::Vector3d& c = nodes[static_cast<std::size_t>(k)];
    const Eigen::Vector3d axis = (nodes[static_cast<std::size_t>(k) + 1] - c).normalized();
    // Draws happen whether or not a sample is kept, so hiding a component does not
    // change the samples of the others.
    for (int i = 0; i < s.samples_per_ball; ++i) {
      const Eigen::Vector3d n = rng.unit();
      const double noise = s.noise_sigma * rng.normal();
      const Eigen::Vector3d p = c + g.ball_radius * n;
      if (hidden[static_cast<std::size_t>(k)] || n.dot(p) >= 0 || occluded(p)) continue;
      if (s.necks && (inside_neck(p, k) || (k > 0 && inside_neck(p, k - 1)))) continue;
      emit(p, noise);
    }
    if (!s.necks) continue;
    const Eigen::Vector3d e1 = axis.unitOrthogonal();
    const Eigen::Vector3d e2 = axis.cross(e1);
    for (int i = 0; i < s.samples_per_neck; ++i) {
      const double t = rng.uniform() * g.neck_length;
      const double phi = 2 * std::numbers::pi * rng.uniform();
      const Eigen::Vector3d n = std::cos(phi) * e1 + std::sin(phi) * e2;
      const double noise = s.noise_sigma * rng.normal();
      const Eigen::Vector3d p = c + t * axis + g.neck_radius * n;
      if (hidden[static_cast<std::size_t>(k)] || n.dot(p) >= 0 || (p - c).norm() < g.ball_radius)
        continue;
      if (k + 1 < g.count && (p - nodes[static_cast<std::size_t>(k) + 1]).norm() < g.ball_radius)
        continue;
      if (occluded(p)) continue;
      emit(p, noise);
    }
  }
  return cloud;
}

Nodes demo_nodes(const ComponentGeometry& g, int frame, double fps) {
  const double t = frame / fps;
  const double w = 2 * std::numbers::pi / 4.0;  // 4 s period
  std::vector<double> bends(static_cast<std::size_t>(g.count - 1));
  const double c = 0.12 * std::sin(w * t);        // C component [rad per joint]
  const double s = 0.10 * std::sin(0.5 * w * t);  // S component
  for (std::size_t k = 0; k < bends.size(); ++k) {
    bends[k] = c + (2 * k + 1 < bends.size() ? s : -s);
  }
  Eigen::Isometry3d X_CB = Eigen::Isometry3d::Identity();
  X_CB.translation() =
      Eigen::Vector3d(-0.24 + 0.02 * std::sin(0.7 * w * t), 0.03 * std::sin(0.3 * w * t), 0.6);
  // Tilt the bending plane toward the camera a little so the link is seen obliquely.
  X_CB.linear() = Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitX()).toRotationMatrix();
  return chain_nodes(g, bends, X_CB);
}

}  // namespace linksight::sim
