#include "linksight/tracker/chain_fit.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace linksight {
namespace {

// The chain at one linearization point: centres, axes and each axis's tangent basis.
struct Frames {
  Nodes centre;                           // count + 1 (the last is the tip node)
  std::vector<Eigen::Vector3d> t1, t2;    // tangents of axis k, a rotation's directions
};

Frames frames_of(const ChainState& chain, double pitch) {
  Frames f;
  f.centre = chain.nodes(pitch);
  for (const Eigen::Vector3d& a : chain.axis) {
    const Eigen::Vector3d t = a.unitOrthogonal();
    f.t1.push_back(t);
    f.t2.push_back(a.cross(t));
  }
  return f;
}

// Distance from p to component k's surface: ball of radius r at c_k ∪ capsule of radius
// r_n around [c_k, c_k + L a_k]. `s` is the capsule parameter of the nearest point and
// `neck` whether the capsule is nearer than the ball.
struct Part {
  double distance = std::numeric_limits<double>::infinity();
  bool neck = false;
  double s = 0.0;
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();  // outward, at the nearest point
};

Part component_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& c,
                        const Eigen::Vector3d& a, const ComponentGeometry& g) {
  Part out;
  const Eigen::Vector3d d = p - c;
  const double dn = d.norm();
  out.distance = dn - g.ball_radius;
  out.normal = dn > 0 ? Eigen::Vector3d(d / dn) : a;
  const double s = std::clamp(d.dot(a), 0.0, g.neck_length);
  const Eigen::Vector3d e = d - s * a;
  const double en = e.norm();
  if (en - g.neck_radius < out.distance) {
    out.distance = en - g.neck_radius;
    out.neck = true;
    out.s = s;
    out.normal = en > 0 ? Eigen::Vector3d(e / en) : a.unitOrthogonal();
  }
  return out;
}

struct Hit {
  int k = -1;
  Part part;
};

Hit nearest(const Eigen::Vector3d& p, const Frames& f, const ChainState& chain,
            const ComponentGeometry& g) {
  // Component k's surface lies within `reach` of its centre, so a point at |p - c_k| is at
  // least |p - c_k| - reach from it: components that cannot beat the best are skipped.
  const double reach = std::max(g.ball_radius, g.neck_length + g.neck_radius);
  Hit h;
  for (std::size_t k = 0; k < chain.axis.size(); ++k) {
    if ((p - f.centre[k]).norm() - reach >= h.part.distance) continue;
    const Part part = component_distance(p, f.centre[k], chain.axis[k], g);
    if (part.distance < h.part.distance) {
      h.k = static_cast<int>(k);
      h.part = part;
    }
  }
  return h;
}

double huber(double r, double h) {
  const double a = std::abs(r);
  return a <= h ? 0.5 * r * r : h * (a - 0.5 * h);
}

// The robust cost of the chain over the points; points beyond max_distance count as if
// there, so that a step that pushes points out does not look cheaper. Also the inliers'
// count and sum of squared distances.
struct Cost {
  double robust = 0;
  std::size_t inliers = 0;
  double sum2 = 0;
};
Cost cost(const PointsView& pts, const ChainState& chain, const ComponentGeometry& g,
          const ChainFitParams& params) {
  const Frames f = frames_of(chain, g.pitch);
  Cost c;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const Eigen::Vector3d p(pts.x[i], pts.y[i], pts.z[i]);
    const double r = nearest(p, f, chain, g).part.distance;
    c.robust += huber(std::min(std::abs(r), params.max_distance), params.huber);
    if (std::abs(r) <= params.max_distance) {
      ++c.inliers;
      c.sum2 += r * r;
    }
  }
  return c;
}

ChainState stepped(const ChainState& chain, const Frames& f, const Eigen::VectorXd& dx) {
  ChainState out = chain;
  out.c0 += dx.head<3>();
  for (std::size_t k = 0; k < chain.axis.size(); ++k) {
    const Eigen::Index j = 3 + 2 * static_cast<Eigen::Index>(k);
    const Eigen::Vector3d& a = chain.axis[k];
    // The rotation that moves a by dx_j t1 + dx_{j+1} t2 to first order.
    const Eigen::Vector3d w = dx[j] * a.cross(f.t1[k]) + dx[j + 1] * a.cross(f.t2[k]);
    const double angle = w.norm();
    out.axis[k] = angle > 0 ? Eigen::Vector3d(Eigen::AngleAxisd(angle, w / angle) * a) : a;
    out.axis[k].normalize();
  }
  return out;
}

}  // namespace

SurfaceHit nearest_surface(const Eigen::Vector3d& p, const ChainState& chain,
                           const ComponentGeometry& geometry) {
  const Hit h = nearest(p, frames_of(chain, geometry.pitch), chain, geometry);
  return {h.k, h.part.distance};
}

ChainFitResult fit_chain(const PointsView& pts, ChainState& chain,
                         const ComponentGeometry& g, const ChainFitParams& params) {
  params.validate();
  g.validate();
  const int count = static_cast<int>(chain.axis.size());
  if (count != g.count)
    throw std::invalid_argument("fit_chain: the chain has " + std::to_string(count) +
                                " axes, the geometry " + std::to_string(g.count) + " components");
  const Eigen::Index n = 3 + 2 * count;
  ChainFitResult result;
  double lambda = 1e-4;  // damping, relative to the diagonal (Levenberg-Marquardt)
  Cost current;          // of `chain`, from the pass that linearizes at it
  Eigen::MatrixXd H(n, n);
  Eigen::VectorXd b(n), J(n);
  for (int it = 0; it < params.max_iterations; ++it) {
    // One pass: the association, the normal equations and the cost at the current chain.
    const Frames f = frames_of(chain, g.pitch);
    H.setZero();
    b.setZero();
    current = {};
    for (std::size_t i = 0; i < pts.size(); ++i) {
      const Eigen::Vector3d p(pts.x[i], pts.y[i], pts.z[i]);
      const Hit hit = nearest(p, f, chain, g);
      const double r = hit.part.distance;
      current.robust += huber(std::min(std::abs(r), params.max_distance), params.huber);
      if (hit.k < 0 || std::abs(r) > params.max_distance) continue;
      ++current.inliers;
      current.sum2 += r * r;
      // dr/dx: moving centre k by dc changes r by -n.dc; turning axis j < k by a tangent
      // moves centre k by pitch along it; turning axis k moves the neck point by s along it.
      const Eigen::Vector3d& nrm = hit.part.normal;
      J.setZero();
      J.head<3>() = -nrm;
      for (int j = 0; j <= hit.k; ++j) {
        const double lever = j < hit.k ? g.pitch : (hit.part.neck ? hit.part.s : 0.0);
        if (lever == 0.0) continue;
        const auto sj = static_cast<std::size_t>(j);
        J[3 + 2 * j] = -lever * nrm.dot(f.t1[sj]);
        J[4 + 2 * j] = -lever * nrm.dot(f.t2[sj]);
      }
      const double w = std::abs(r) <= params.huber ? 1.0 : params.huber / std::abs(r);
      H.selfadjointView<Eigen::Lower>().rankUpdate(J, w);
      b -= w * r * J;
    }
    H = H.selfadjointView<Eigen::Lower>();
    // Damped steps until one lowers the cost. A parameter no point constrains (an axis
    // of a hidden component) has a zero row: the floor keeps it where it is.
    bool accepted = false, converged = false;
    for (int attempt = 0; attempt < 12 && !accepted; ++attempt) {
      Eigen::MatrixXd A = H;
      for (Eigen::Index d = 0; d < n; ++d) A(d, d) += lambda * H(d, d) + 1e-12;
      const Eigen::VectorXd dx = A.ldlt().solve(b);
      ChainState trial = stepped(chain, f, dx);
      limit_bends(trial, params.cone_limit);
      double moved = 0;
      const Nodes after = trial.nodes(g.pitch);
      for (std::size_t k = 0; k < after.size(); ++k)
        moved = std::max(moved, (after[k] - f.centre[k]).norm());
      if (moved <= params.tolerance) {  // the step would move nothing: a minimum
        converged = true;
        break;
      }
      const Cost c = cost(pts, trial, g, params);
      if (c.robust <= current.robust) {
        chain = std::move(trial);
        current = c;
        lambda = std::max(lambda / 10, 1e-9);
        accepted = true;
        result.iterations = it + 1;
      } else {
        lambda *= 10;
      }
    }
    if (!accepted || converged) break;  // no damped step lowers the cost, or none moves
  }
  result.inliers = current.inliers;
  result.rms = current.inliers ? std::sqrt(current.sum2 / static_cast<double>(current.inliers)) : 0.0;
  return result;
}

}  // namespace linksight
