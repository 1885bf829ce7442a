#include "linksight/tracker/init.hpp"

#include "linksight/tracker/seed.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cstdint>
#include <cmath>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <vector>

namespace linksight {
namespace {

// Deterministic stride thinning: the same cloud always gives the same subset.
struct Thinned {
  std::vector<double> x, y, z;
};
Thinned thin(const PointsView& p, std::size_t max_points) {
  const std::size_t n = p.size();
  const std::size_t stride =
      (max_points == 0 || n <= max_points) ? 1 : (n + max_points - 1) / max_points;
  Thinned t;
  const std::size_t m = (n + stride - 1) / stride;
  t.x.reserve(m);
  t.y.reserve(m);
  t.z.reserve(m);
  for (std::size_t i = 0; i < n; i += stride) {
    t.x.push_back(p.x[i]);
    t.y.push_back(p.y[i]);
    t.z.push_back(p.z[i]);
  }
  return t;
}

struct Axes {
  Eigen::Vector3d centroid;
  Eigen::Matrix3d E;  // columns: principal axes, largest variance first
};
Axes principal_axes(const Thinned& t) {
  const std::size_t n = t.x.size();
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < n; ++i) c += Eigen::Vector3d(t.x[i], t.y[i], t.z[i]);
  c /= static_cast<double>(n);
  Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d d = Eigen::Vector3d(t.x[i], t.y[i], t.z[i]) - c;
    C += d * d.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(C);
  Axes a;
  a.centroid = c;
  // Eigen sorts eigenvalues ascending.
  a.E.col(0) = es.eigenvectors().col(2);
  a.E.col(1) = es.eigenvectors().col(1);
  a.E.col(2) = es.eigenvectors().col(0);
  return a;
}

// Node 0 at the end nearer the previous node 0 (keeps topology across
// re-initialization). Without a previous output, node 0 is the end with the smaller
// coordinate along the camera axis in which the link extends most (left end of a
// horizontal link, top end of a hanging one, near end of one pointing away).
void orient(Nodes& nodes, const Nodes* previous) {
  const Eigen::Vector3d& a = nodes.front();
  const Eigen::Vector3d& b = nodes.back();
  bool flip = false;
  if (previous != nullptr && previous->size() == nodes.size()) {
    const Eigen::Vector3d& pa = previous->front();
    const Eigen::Vector3d& pb = previous->back();
    flip = (a - pb).norm() + (b - pa).norm() < (a - pa).norm() + (b - pb).norm();
  } else {
    Eigen::Index axis = 0;
    (b - a).cwiseAbs().maxCoeff(&axis);
    flip = b[axis] < a[axis];
  }
  if (flip) std::reverse(nodes.begin(), nodes.end());
}

double covariance(const std::vector<double>& a, const std::vector<double>& b) {
  double ma = 0, mb = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    ma += a[i];
    mb += b[i];
  }
  ma /= static_cast<double>(a.size());
  mb /= static_cast<double>(a.size());
  double s = 0;
  for (std::size_t i = 0; i < a.size(); ++i) s += (a[i] - ma) * (b[i] - mb);
  return s;
}

Nodes init_paper(const Thinned& t, int n_nodes, int order) {
  const auto [xmin, xmax] = std::minmax_element(t.x.begin(), t.x.end());
  const auto [zmin, zmax] = std::minmax_element(t.z.begin(), t.z.end());
  const Polynomial a = fit_polynomial(t.x, t.y, order);  // y = a(x), Eq. (9) first line
  const Polynomial b = fit_polynomial(t.z, t.y, order);  // y = b(z), Eq. (9) second line
  const double dx = *xmax - *xmin;
  const double dz = *zmax - *zmin;
  // The two curves are sampled at constant intervals over their marginal ranges; z runs
  // in the direction that correlates with x so that both samplings walk the same way.
  const bool z_rises = covariance(t.x, t.z) >= 0.0;
  double y_mean = 0;
  for (double v : t.y) y_mean += v;
  y_mean /= static_cast<double>(t.y.size());
  Nodes nodes(static_cast<std::size_t>(n_nodes));
  for (int k = 0; k < n_nodes; ++k) {
    const double f = n_nodes > 1 ? static_cast<double>(k) / (n_nodes - 1) : 0.5;
    const double xk = *xmin + f * dx;
    const double zk = z_rises ? *zmin + f * dz : *zmax - f * dz;
    // Each curve's y is weighted by the span of its abscissa: a curve fitted over a
    // near-constant abscissa carries no shape information.
    const double yk = dx + dz > 0 ? (dx * a(xk) + dz * b(zk)) / (dx + dz) : y_mean;
    nodes[static_cast<std::size_t>(k)] = Eigen::Vector3d(xk, yk, zk);
  }
  return nodes;
}

Nodes init_pca(const Thinned& t, int n_nodes, int order, double pitch) {
  const Axes ax = principal_axes(t);
  const std::size_t n = t.x.size();
  std::vector<double> u(n), v(n), w(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d d = Eigen::Vector3d(t.x[i], t.y[i], t.z[i]) - ax.centroid;
    u[i] = d.dot(ax.E.col(0));
    v[i] = d.dot(ax.E.col(1));
    w[i] = d.dot(ax.E.col(2));
  }
  const Polynomial pv = fit_polynomial(u, v, order);
  const Polynomial pw = fit_polynomial(u, w, order);
  const auto [umin_it, umax_it] = std::minmax_element(u.begin(), u.end());
  const double umin = *umin_it, umax = *umax_it;
  auto curve = [&](double uu) {
    return Eigen::Vector3d(ax.centroid + uu * ax.E.col(0) + pv(uu) * ax.E.col(1) +
                           pw(uu) * ax.E.col(2));
  };
  // Arc-length table of the fitted curve over the cloud's range.
  constexpr int kSamples = 256;
  std::vector<Eigen::Vector3d> pts(kSamples);
  std::vector<double> s(kSamples, 0.0);
  for (int i = 0; i < kSamples; ++i) {
    pts[i] = curve(umin + (umax - umin) * i / (kSamples - 1));
    if (i > 0) s[i] = s[i - 1] + (pts[i] - pts[i - 1]).norm();
  }
  const double length = s.back();
  auto at = [&](double sk) -> Eigen::Vector3d {
    if (length <= 0.0) return pts.front() + (sk - length / 2) * ax.E.col(0);
    if (sk <= 0.0) {
      const Eigen::Vector3d tan = (pts[1] - pts[0]).normalized();
      return pts[0] + sk * tan;
    }
    if (sk >= length) {
      const Eigen::Vector3d tan = (pts[kSamples - 1] - pts[kSamples - 2]).normalized();
      return pts[kSamples - 1] + (sk - length) * tan;
    }
    const auto it = std::upper_bound(s.begin(), s.end(), sk);
    const std::size_t j = static_cast<std::size_t>(it - s.begin());
    const double seg = s[j] - s[j - 1];
    const double f = seg > 0 ? (sk - s[j - 1]) / seg : 0.0;
    return pts[j - 1] + f * (pts[j] - pts[j - 1]);
  };
  // Nodes at the known pitch, centred on the visible part of the curve.
  Nodes nodes(static_cast<std::size_t>(n_nodes));
  for (int k = 0; k < n_nodes; ++k) {
    nodes[static_cast<std::size_t>(k)] = at(length / 2 + (k - (n_nodes - 1) / 2.0) * pitch);
  }
  return nodes;
}

}  // namespace

std::string_view to_string(InitMethod method) {
  return method == InitMethod::paper ? "paper" : "pca";
}

InitMethod parse_init(std::string_view name) {
  if (name == "paper") return InitMethod::paper;
  if (name == "pca") return InitMethod::pca;
  throw std::invalid_argument("unknown init '" + std::string(name) + "' (expected paper or pca)");
}

void InitParams::validate() const {
  fields::check(*this, "lsq_init");
  if (!(std::isfinite(pitch) && pitch > 0)) fields::fail("lsq_init", "pitch", pitch, "must be > 0");
}

double Polynomial::operator()(double u) const {
  const double t = (u - u0) / scale;
  double r = 0.0;
  for (Eigen::Index k = coeffs.size() - 1; k >= 0; --k) r = r * t + coeffs[k];  // Horner
  return r;
}

Polynomial fit_polynomial(std::span<const double> u, std::span<const double> v, int order) {
  if (u.size() != v.size() || u.empty()) {
    throw std::invalid_argument("fit_polynomial: need equally many u and v values, at least 1");
  }
  const std::size_t n = u.size();
  Polynomial p;
  double mean = 0;
  for (double x : u) mean += x;
  p.u0 = mean / static_cast<double>(n);
  double spread = 0;
  for (double x : u) spread = std::max(spread, std::abs(x - p.u0));
  p.scale = spread > 0 ? spread : 1.0;
  // A constant abscissa carries no slope information: fit the mean only.
  const int m = spread > 0 ? std::min<int>(order, static_cast<int>(n) - 1) : 0;
  Eigen::MatrixXd A(static_cast<Eigen::Index>(n), m + 1);
  Eigen::VectorXd b(static_cast<Eigen::Index>(n));
  for (std::size_t i = 0; i < n; ++i) {
    const double t = (u[i] - p.u0) / p.scale;
    double tk = 1.0;
    for (int k = 0; k <= m; ++k, tk *= t) A(static_cast<Eigen::Index>(i), k) = tk;
    b[static_cast<Eigen::Index>(i)] = v[i];
  }
  p.coeffs = A.colPivHouseholderQr().solve(b);  // minimizes Eq. (10)
  return p;
}

Nodes lsq_init(const PointsView& points, int n_nodes, const InitParams& params,
               const Nodes* previous) {
  params.validate();
  if (points.size() == 0 || n_nodes < 2) {
    throw std::invalid_argument("lsq_init: need at least 1 point and 2 nodes");
  }
  const Thinned t = thin(points, params.max_points);
  Nodes nodes = params.method == InitMethod::paper
                    ? init_paper(t, n_nodes, params.poly_order)
                    : init_pca(t, n_nodes, params.poly_order, params.pitch);
  orient(nodes, previous);
  return nodes;
}

std::string_view to_string(SomInit method) {
  return method == SomInit::straight_line ? "straight-line" : "random-sample";
}

SomInit parse_som_init(std::string_view name) {
  if (name == "straight-line") return SomInit::straight_line;
  if (name == "random-sample") return SomInit::random_sample;
  throw std::invalid_argument("unknown SOM init '" + std::string(name) +
                              "' (expected straight-line or random-sample)");
}

Nodes som_init(const PointsView& points, int n_nodes, SomInit method, std::uint64_t seed) {
  if (points.size() == 0 || n_nodes < 2) {
    throw std::invalid_argument("som_init: need at least 1 point and 2 nodes");
  }
  Nodes nodes(static_cast<std::size_t>(n_nodes));
  if (method == SomInit::random_sample) {
    std::uint64_t state = seed;
    for (auto& q : nodes) {
      const std::size_t i = splitmix64(state) % points.size();
      q = Eigen::Vector3d(points.x[i], points.y[i], points.z[i]);
    }
    return nodes;  // deliberately unordered: the baseline has no topology prior
  }
  const Thinned t = thin(points, 0);
  const Axes ax = principal_axes(t);
  double umin = 0, umax = 0;
  for (std::size_t i = 0; i < t.x.size(); ++i) {
    const double uu = (Eigen::Vector3d(t.x[i], t.y[i], t.z[i]) - ax.centroid).dot(ax.E.col(0));
    umin = std::min(umin, uu);
    umax = std::max(umax, uu);
  }
  for (int k = 0; k < n_nodes; ++k) {
    const double f = static_cast<double>(k) / (n_nodes - 1);
    nodes[static_cast<std::size_t>(k)] = ax.centroid + (umin + f * (umax - umin)) * ax.E.col(0);
  }
  orient(nodes, nullptr);
  return nodes;
}

std::vector<std::size_t> largest_cluster(const PointsView& points, double cell) {
  if (!(cell >= 1e-4)) throw std::invalid_argument("largest_cluster: cell must be >= 1e-4 m");
  const std::size_t n = points.size();
  // Cells keyed by their integer coordinates (points are within kMaxCoordinate, so 21
  // bits each hold any cell of 1 mm or more), numbered in order of first appearance.
  const auto key = [](std::int64_t i, std::int64_t j, std::int64_t k) {
    constexpr std::int64_t kBias = std::int64_t{1} << 20;
    return ((i + kBias) << 42) | ((j + kBias) << 21) | (k + kBias);
  };
  std::unordered_map<std::int64_t, std::size_t> cell_of;
  std::vector<std::array<std::int64_t, 3>> coords;
  std::vector<std::size_t> point_cell(n);
  // Within 21 bits each: |coordinate| / cell below 2^20 (100 m at 0.1 mm).
  const double limit = static_cast<double>(std::int64_t{1} << 20) * cell;
  for (std::size_t p = 0; p < n; ++p) {
    if (!(std::abs(points.x[p]) < limit && std::abs(points.y[p]) < limit &&
          std::abs(points.z[p]) < limit))
      throw std::invalid_argument("largest_cluster: point " + std::to_string(p) +
                                  " is not finite or beyond " + std::to_string(limit) + " m");
    const std::array<std::int64_t, 3> c{static_cast<std::int64_t>(std::floor(points.x[p] / cell)),
                                        static_cast<std::int64_t>(std::floor(points.y[p] / cell)),
                                        static_cast<std::int64_t>(std::floor(points.z[p] / cell))};
    const auto [it, fresh] = cell_of.try_emplace(key(c[0], c[1], c[2]), coords.size());
    if (fresh) coords.push_back(c);
    point_cell[p] = it->second;
  }
  // Union-find over the cells, the root always the lowest-numbered cell of its set.
  std::vector<std::size_t> parent(coords.size());
  for (std::size_t c = 0; c < parent.size(); ++c) parent[c] = c;
  const auto find = [&](std::size_t c) {
    while (parent[c] != c) c = parent[c] = parent[parent[c]];
    return c;
  };
  for (std::size_t c = 0; c < coords.size(); ++c) {
    for (std::int64_t di = -1; di <= 1; ++di)
      for (std::int64_t dj = -1; dj <= 1; ++dj)
        for (std::int64_t dk = -1; dk <= 1; ++dk) {
          const auto it = cell_of.find(key(coords[c][0] + di, coords[c][1] + dj, coords[c][2] + dk));
          if (it == cell_of.end()) continue;
          const std::size_t a = find(c), b = find(it->second);
          if (a != b) parent[std::max(a, b)] = std::min(a, b);
        }
  }
  std::vector<std::size_t> size(coords.size(), 0);
  for (std::size_t p = 0; p < n; ++p) ++size[find(point_cell[p])];
  // The first point's cell numbers lowest among its cluster's, so scanning roots in cell
  // order breaks ties by the lowest point index.
  std::size_t best = 0;
  for (std::size_t c = 0; c < size.size(); ++c)
    if (size[c] > size[best]) best = c;
  std::vector<std::size_t> out;
  for (std::size_t p = 0; p < n; ++p)
    if (find(point_cell[p]) == best) out.push_back(p);
  return out;
}

}  // namespace linksight
