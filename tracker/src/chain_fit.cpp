#include "linksight/tracker/chain_fit.hpp"

#include "chain_pass.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace linksight {
namespace {

using Frames = detail::ChainFrames;
using Sums = detail::ChainSums;
using detail::Mat5;
using detail::Vec5;

Frames frames_of(const ChainState& chain, const ComponentGeometry& g) {
  // Associations hold a component's index in 16 bits.
  if (chain.axis.size() > static_cast<std::size_t>(std::numeric_limits<std::int16_t>::max()))
    throw std::invalid_argument("chain-fit: " + std::to_string(chain.axis.size()) +
                                " components; at most 32767");
  Frames f;
  f.centre = chain.nodes(g.pitch);
  for (std::size_t k = 0; k < chain.axis.size(); ++k) {
    const Eigen::Vector3d& a = chain.axis[k];
    const Eigen::Vector3d t = a.unitOrthogonal();
    f.t1.push_back(t);
    f.t2.push_back(a.cross(t));
    f.cx.push_back(f.centre[k].x());
    f.cy.push_back(f.centre[k].y());
    f.cz.push_back(f.centre[k].z());
    f.ax.push_back(a.x());
    f.ay.push_back(a.y());
    f.az.push_back(a.z());
  }
  f.search = detail::search_frames(f, g);
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

// The distance only (the search's inner step): d = p - c_k, dn2 = |d|^2. `norm` is the
// distance from p to the nearest point of the ball's centre or the neck's axis, which the
// normal is divided by.
struct Candidate {
  double distance;
  double s;
  bool neck;
  double norm;
};
inline Candidate candidate(double dx, double dy, double dz, double dn2, double ax, double ay,
                           double az, const ComponentGeometry& g) {
  const double dn = std::sqrt(dn2);
  Candidate out{dn - g.ball_radius, 0.0, false, dn};
  const double s = std::clamp(dx * ax + dy * ay + dz * az, 0.0, g.neck_length);
  const double ex = dx - s * ax, ey = dy - s * ay, ez = dz - s * az;
  const double en = std::sqrt(ex * ex + ey * ey + ez * ez);
  const double neck = en - g.neck_radius;
  if (neck < out.distance) out = {neck, s, true, en};
  return out;
}

struct Hit {
  int k = -1;
  Part part;
};

// The hit on component k from its candidate: the outward normal at the nearest point.
Hit hit_of(const Eigen::Vector3d& p, const Frames& f, std::size_t k, const Candidate& c) {
  Hit h;
  h.k = static_cast<int>(k);
  h.part.distance = c.distance;
  h.part.neck = c.neck;
  h.part.s = c.s;
  const Eigen::Vector3d a(f.ax[k], f.ay[k], f.az[k]);
  const Eigen::Vector3d d = p - Eigen::Vector3d(f.cx[k], f.cy[k], f.cz[k]);
  const Eigen::Vector3d e = c.neck ? Eigen::Vector3d(d - c.s * a) : d;
  h.part.normal = c.norm > 0 ? Eigen::Vector3d(e / c.norm) : (c.neck ? a.unitOrthogonal() : a);
  return h;
}

// Component k's distance to p with the normal there.
Hit hit_on(const Eigen::Vector3d& p, const Frames& f, const ComponentGeometry& g,
           std::size_t k) {
  const double dx = p.x() - f.cx[k], dy = p.y() - f.cy[k], dz = p.z() - f.cz[k];
  return hit_of(p, f, k,
                candidate(dx, dy, dz, dx * dx + dy * dy + dz * dz, f.ax[k], f.ay[k], f.az[k], g));
}

// The nearest component (chain_search.hpp's float search) and its hit in double.
Hit nearest(const Eigen::Vector3d& p, const Frames& f, const ComponentGeometry& g) {
  if (f.cx.empty()) return {};
  const float x = static_cast<float>(p.x()), y = static_cast<float>(p.y()),
              z = static_cast<float>(p.z());
  std::int16_t k = 0;
  detail::chain_search_range(&x, &y, &z, 0, 1, 1, f.search, &k);
  return hit_on(p, f, g, static_cast<std::size_t>(k));
}

double huber(double r, double h) {
  const double a = std::abs(r);
  return a <= h ? 0.5 * r * r : h * (a - 0.5 * h);
}

// Which component each point is taken to lie on. A pass either searches (and records
// what it found, when `assoc` is given) or, after a step too small to change it, reuses
// the recorded one: a pass then costs one component's distance per point, not a search.
struct Association {
  std::int16_t* assoc = nullptr;
  bool reuse = false;
  // The robust cost alone (to choose between starts): no normal equations, no normals.
  bool cost_only = false;
};

void accumulate(const PointsView& pts, std::size_t begin, std::size_t end, std::size_t stride,
                const Frames& f, const ComponentGeometry& g, const ChainFitParams& params,
                Association a, Sums& s) {
  if (f.cx.empty() || begin >= end) return;
  // The block's association first (the float search, chain_search.hpp), then each point's
  // residual and Jacobian in double on its component, as a reusing pass computes them.
  std::vector<std::int16_t> local;
  const std::int16_t* assoc = a.assoc != nullptr ? a.assoc + begin : nullptr;
  if (!a.reuse) {
    std::int16_t* out = a.assoc != nullptr ? a.assoc + begin : nullptr;
    if (out == nullptr) {
      local.resize(end - begin);
      out = local.data();
    }
    detail::chain_search_range(pts.x.data() + begin, pts.y.data() + begin, pts.z.data() + begin,
                               0, end - begin, stride, f.search, out);
    assoc = out;
  }
  for (std::size_t i = begin; i < end; i += stride) {
    const Eigen::Vector3d p(pts.x[i], pts.y[i], pts.z[i]);
    const auto k = static_cast<std::size_t>(assoc[i - begin]);
    if (a.cost_only) {  // the robust cost as below, from the distance alone
      const double dx = p.x() - f.cx[k], dy = p.y() - f.cy[k], dz = p.z() - f.cz[k];
      const double r = candidate(dx, dy, dz, dx * dx + dy * dy + dz * dz, f.ax[k], f.ay[k],
                                 f.az[k], g)
                           .distance;
      s.robust += huber(std::min(std::abs(r), params.max_distance), params.huber);
      continue;
    }
    const Hit hit = hit_on(p, f, g, k);
    const double r = hit.part.distance;
    // Points beyond max_distance count as if there, so that a step that pushes points
    // out does not look cheaper.
    s.robust += huber(std::min(std::abs(r), params.max_distance), params.huber);
    if (std::abs(r) > params.max_distance) continue;
    ++s.inliers;
    ++s.count[k];
    s.sum2 += r * r;
    // dr/du: moving centre k by dc changes r by -n.dc; turning axis k moves the neck
    // point by s along the turn's tangent (a ball point not at all).
    const Eigen::Vector3d& nrm = hit.part.normal;
    const double lever = hit.part.neck ? hit.part.s : 0.0;
    Vec5 J;
    J << -nrm, -lever * nrm.dot(f.t1[k]), -lever * nrm.dot(f.t2[k]);
    const double w = std::abs(r) <= params.huber ? 1.0 : params.huber / std::abs(r);
    Mat5& H = s.H[k];  // lower triangle only
    for (int c = 0; c < 5; ++c)
      for (int r2 = c; r2 < 5; ++r2) H(r2, c) += w * J[r2] * J[c];
    s.b[k] -= w * r * J;
  }
}

constexpr std::size_t kBlock = detail::kChainBlock;

// Every `stride`-th point of each block, from the block's first.
Sums pass(const PointsView& pts, const Frames& f, const ChainState& chain,
          const ComponentGeometry& g, const ChainFitParams& params, int threads,
          std::size_t stride = 1, Association a = {}) {
  const std::size_t components = chain.axis.size();
  const std::size_t blocks = (pts.size() + kBlock - 1) / kBlock;
  Sums total(components);
  if (threads <= 1 || blocks <= 1) {
    for (std::size_t blk = 0; blk < blocks; ++blk) {
      Sums s(components);
      accumulate(pts, blk * kBlock, std::min(pts.size(), (blk + 1) * kBlock), stride, f, g, params,
                 a, s);
      total.add(s);
    }
    return total;
  }
  std::vector<Sums> partial(blocks, Sums(components));
  const auto n_blocks = static_cast<std::ptrdiff_t>(blocks);
#pragma omp parallel for num_threads(threads) schedule(dynamic, 1)
  for (std::ptrdiff_t blk = 0; blk < n_blocks; ++blk) {
    const auto b = static_cast<std::size_t>(blk);
    // Summed in a Sums of the thread's own, not in partial[b] itself: neighbouring blocks'
    // scalar sums share a cache line there, which two threads adding to every point would
    // pass back and forth.
    Sums s(components);
    accumulate(pts, b * kBlock, std::min(pts.size(), (b + 1) * kBlock), stride, f, g, params,
               a, s);
    partial[b] = std::move(s);
  }
  for (const Sums& s : partial) total.add(s);
  return total;
}

// The chain's normal equations from the components' (Gauss-Newton in x = [dc0;
// dtheta_0..dtheta_{count-1}]): u_k = P_k x with dc_k = dc0 + pitch sum_{j<k} T_j
// dtheta_j, T_j = [t1_j t2_j]. By column group (g = 0: dc0, with G_0 = I; g = j + 1:
// dtheta_j, with G_g = pitch T_j, which moves the centres of components k >= g), H's block
// (g, h) is G_g^T (sum over k >= max(g, h) of component k's centre block) G_h, plus each
// component's cross and rotation blocks: suffix sums make it O(count^2) 3x3 products
// instead of count dense (3 + 2 count)^2 sandwiches.
void assemble(const Sums& s, const Frames& f, double pitch, Eigen::MatrixXd& H,
              Eigen::VectorXd& b) {
  const std::size_t K = s.H.size();
  H.setZero();
  b.setZero();
  std::vector<Mat5> full(K);
  std::vector<Eigen::Matrix3d> S(K + 1, Eigen::Matrix3d::Zero());
  std::vector<Eigen::Vector3d> sb(K + 1, Eigen::Vector3d::Zero());
  for (std::size_t k = K; k-- > 0;) {
    full[k] = s.H[k].selfadjointView<Eigen::Lower>();
    S[k] = S[k + 1] + full[k].topLeftCorner<3, 3>();
    sb[k] = sb[k + 1] + s.b[k].head<3>();
  }
  // G_g for g >= 1 (3 x 2); col(g): group g's first column in x.
  std::vector<Eigen::Matrix<double, 3, 2>> G(K + 1);
  for (std::size_t g = 1; g <= K; ++g) {
    G[g].col(0) = pitch * f.t1[g - 1];
    G[g].col(1) = pitch * f.t2[g - 1];
  }
  const auto col = [](std::size_t g) {
    return g == 0 ? Eigen::Index{0} : static_cast<Eigen::Index>(3 + 2 * (g - 1));
  };
  H.topLeftCorner<3, 3>() = S[0];
  b.head<3>() = sb[0];
  for (std::size_t g = 1; g < K; ++g) {  // G_K moves no centre (no component k >= K)
    const Eigen::Index c = col(g);
    const Eigen::Matrix<double, 2, 3> GtS = G[g].transpose() * S[g];
    H.block<2, 2>(c, c) = GtS * G[g];
    H.block<2, 3>(c, 0) = GtS;  // with dc0: G_0 = I
    H.block<3, 2>(0, c) = GtS.transpose();
    for (std::size_t h = 1; h < g; ++h) {
      const Eigen::Matrix2d blk = GtS * G[h];  // max(g, h) = g
      H.block<2, 2>(c, col(h)) = blk;
      H.block<2, 2>(col(h), c) = blk.transpose();
    }
    b.segment<2>(c) = G[g].transpose() * sb[g];
  }
  for (std::size_t k = 0; k < K; ++k) {
    const Eigen::Index r = col(k + 1);
    const Eigen::Matrix<double, 3, 2> Hcr = full[k].topRightCorner<3, 2>();
    // Component k's rotation against every group that moves its centre (g <= k).
    H.block<3, 2>(0, r) += Hcr;
    H.block<2, 3>(r, 0) += Hcr.transpose();
    for (std::size_t g = 1; g <= k; ++g) {
      const Eigen::Matrix2d blk = G[g].transpose() * Hcr;
      H.block<2, 2>(col(g), r) += blk;
      H.block<2, 2>(r, col(g)) += blk.transpose();
    }
    H.block<2, 2>(r, r) += full[k].bottomRightCorner<2, 2>();
    b.segment<2>(r) += s.b[k].tail<2>();
  }
}

// The shape prior (the link holds its shape unless pushed): joint k's bend, as the
// difference of its axes a_k - a_{k-1}, stays near the prior chain's. A joint the points
// constrain moves as they say (the prior weighs as much as a few points); a hidden one
// keeps its bend, so the hidden part moves rigidly with what is seen. Adds the prior's
// normal equations to H, b when given, and returns its cost.
double shape_prior(const ChainState& chain, const Frames& f, const ChainState& shape,
                   double weight, Eigen::MatrixXd* H, Eigen::VectorXd* b) {
  double cost = 0;
  for (std::size_t k = 1; k < chain.axis.size(); ++k) {
    const Eigen::Vector3d r =
        (chain.axis[k] - chain.axis[k - 1]) - (shape.axis[k] - shape.axis[k - 1]);
    cost += 0.5 * weight * r.squaredNorm();
    if (H == nullptr) continue;
    // The step turns a_k by T_k dtheta_k to first order (stepped), T_k = [t1_k t2_k].
    Eigen::Matrix<double, 3, 4> J;
    J << -f.t1[k - 1], -f.t2[k - 1], f.t1[k], f.t2[k];
    const auto c = 3 + 2 * static_cast<Eigen::Index>(k - 1);
    H->block<4, 4>(c, c).noalias() += weight * J.transpose() * J;
    b->segment<4>(c).noalias() -= weight * J.transpose() * r;
  }
  return cost;
}

// The anchor (a known base): ball 0's centre and component 0's axis held near where the
// base puts them, each weighed so that one σ costs what a point at the Huber threshold
// does. Adds its normal equations to H, b when given, and returns its cost.
double anchor_prior(const ChainState& chain, const Frames& f, const ChainAnchor& anchor,
                    double huber_m, Eigen::MatrixXd* H, Eigen::VectorXd* b) {
  const double wp = std::pow(huber_m / anchor.sigma_m, 2);
  const double wa = std::pow(huber_m / anchor.sigma_rad, 2);
  const Eigen::Vector3d rp = chain.c0 - anchor.c0;
  const Eigen::Vector3d ra = chain.axis[0] - anchor.axis0;
  const double cost = 0.5 * wp * rp.squaredNorm() + 0.5 * wa * ra.squaredNorm();
  if (H == nullptr) return cost;
  H->topLeftCorner<3, 3>().diagonal().array() += wp;
  b->head<3>().noalias() -= wp * rp;
  // The step turns a_0 by T_0 dtheta_0 to first order, T_0 = [t1_0 t2_0].
  Eigen::Matrix<double, 3, 2> J;
  J << f.t1[0], f.t2[0];
  H->block<2, 2>(3, 3).noalias() += wa * J.transpose() * J;
  b->segment<2>(3).noalias() -= wa * J.transpose() * ra;
  return cost;
}

// Free space (issue 17, part 3): a component the points hardly show (fewer inliers than
// free_space_below) may be hidden behind something, or it may not be where the chain puts
// it. The depth image tells which: a pixel whose ray passes through the ball and sees a
// surface more than free_space_margin behind it shows free space where the ball would be.
// The ball's image is sampled on a fixed kFreeSpaceGrid x kFreeSpaceGrid grid over its
// bounding square (each sample the pixel under it), so a ball weighs the same at any
// distance. Each sample that shows free space is a residual rho - r < 0 (rho: its ray's
// distance from the centre; zero once the ball has left the ray), with the Jacobian of a
// ball point whose normal points from the centre to the ray, weighed like a point; a
// pixel with a nearer surface (an occluder, the link itself) or none says nothing. Added
// to `s` (H, b, the robust cost; not to the inlier counts) per component; returns the
// rays.
constexpr int kFreeSpaceGrid = 13;

int add_free_space(Sums& s, const Frames& f, const ComponentGeometry& g,
                   const ChainFitParams& params, const DepthView& depth) {
  int rays = 0;
  const double r = g.ball_radius;
  for (std::size_t k = 0; k < s.count.size(); ++k) {
    if (s.count[k] >= params.free_space_below) continue;
    const Eigen::Vector3d& c = f.centre[k];
    if (!(c.z() > r)) continue;  // at or behind the camera: no disc
    const double u0 = depth.fx * c.x() / c.z() + depth.cx;
    const double v0 = depth.fy * c.y() / c.z() + depth.cy;
    const double reach_u = depth.fx * r / (c.z() - r), reach_v = depth.fy * r / (c.z() - r);
    for (int j = 0; j < kFreeSpaceGrid; ++j) {
      const double v = v0 + reach_v * (2.0 * j / (kFreeSpaceGrid - 1) - 1.0);
      if (!(v > -0.5 && v < depth.height - 0.5)) continue;  // also bounds the cast below
      const int iv = static_cast<int>(std::lround(v));
      for (int i = 0; i < kFreeSpaceGrid; ++i) {
        const double u = u0 + reach_u * (2.0 * i / (kFreeSpaceGrid - 1) - 1.0);
        if (!(u > -0.5 && u < depth.width - 0.5)) continue;
        const int iu = static_cast<int>(std::lround(u));
        if (iu < 0 || iu >= depth.width || iv < 0 || iv >= depth.height) continue;
        const float z_obs =
            depth.depth_m[static_cast<std::size_t>(iv) * static_cast<std::size_t>(depth.width) +
                          static_cast<std::size_t>(iu)];
        if (!(z_obs > 0) || !std::isfinite(z_obs)) continue;
        const Eigen::Vector3d ray((iu - depth.cx) / depth.fx, (iv - depth.cy) / depth.fy, 1.0);
        const Eigen::Vector3d d = ray.normalized();
        const double t_c = c.dot(d);
        const Eigen::Vector3d q = t_c * d;  // the ray's point nearest the centre
        const Eigen::Vector3d e = q - c;
        const double rho = e.norm();
        if (!(rho < r) || rho == 0.0) continue;
        const double t_out = t_c + std::sqrt(r * r - rho * rho);
        const double t_obs = static_cast<double>(z_obs) / d.z();
        if (!(t_obs > t_out + params.free_space_margin)) continue;
        const double res = rho - r;
        s.robust += huber(res, params.huber);
        const double w = std::abs(res) <= params.huber ? 1.0 : params.huber / std::abs(res);
        const Eigen::Vector3d n = e / rho;
        Vec5 J;
        J << -n, 0.0, 0.0;
        Mat5& H = s.H[k];
        for (int col = 0; col < 5; ++col)
          for (int row = col; row < 5; ++row) H(row, col) += w * J[row] * J[col];
        s.b[k] -= w * res * J;
        ++rays;
      }
    }
  }
  return rays;
}

// With a base pose: a hidden ball (fewer inliers than hidden_below) is held where the
// anchor says it was last seen, in the base frame moved to this frame. The residual is its
// centre's offset, in u_k's centre part (so it sums per component like a point), weighed
// as the anchor is: one held_sigma_m costs a point at the Huber threshold. Its cost goes
// into the pass's robust cost, as its weight depends on the pass's counts.
void add_held(Sums& s, const Frames& f, const ChainFitParams& params, const ChainAnchor& a) {
  const double w = std::pow(params.huber / a.held_sigma_m, 2);
  for (std::size_t k = 0; k < s.count.size() && k < a.held.size(); ++k) {
    if (!a.held[k] || s.count[k] >= params.hidden_below) continue;
    const Eigen::Vector3d r = f.centre[k] - *a.held[k];
    s.robust += 0.5 * w * r.squaredNorm();
    s.H[k].topLeftCorner<3, 3>().diagonal().array() += w;
    s.b[k].head<3>() -= w * r;
  }
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

void ChainFitParams::validate() const {
  fields::check(*this, "chain_fit");
  constexpr double kDeg = 3.14159265358979323846 / 180;
  if (!(cone_limit >= 0.1 * kDeg && cone_limit <= 89.9 * kDeg))
    fields::fail("chain", "cone_limit_deg", cone_limit / kDeg, "must be in [0.1, 89.9]");
}

double anchor_cost(const ChainState& chain, const ChainAnchor& anchor, const ComponentGeometry& g,
                   const ChainFitParams& params) {
  return anchor_prior(chain, frames_of(chain, g), anchor, params.huber, nullptr, nullptr);
}

SurfaceHit nearest_surface(const Eigen::Vector3d& p, const ChainState& chain,
                           const ComponentGeometry& geometry) {
  const Hit h = nearest(p, frames_of(chain, geometry), geometry);
  return {h.k, h.part.distance};
}

double chain_cost(const PointsView& pts, const ChainState& chain, const ComponentGeometry& g,
                  const ChainFitParams& params, int threads, std::size_t stride) {
  params.validate();
  if (threads <= 0) threads = omp_get_num_procs();
  if (stride == 0) throw std::invalid_argument("chain_cost: stride must be at least 1");
  return pass(pts, frames_of(chain, g), chain, g, params, threads, stride,
              Association{nullptr, false, true})
      .robust;
}

ChainState slide_to_best(const PointsView& pts, const ChainState& start,
                         const ComponentGeometry& g, const ChainFitParams& params,
                         int threads) {
  params.validate();
  if (threads <= 0) threads = omp_get_num_procs();
  if (start.axis.size() != static_cast<std::size_t>(g.count))
    throw std::invalid_argument("slide_to_best: the chain has " +
                                std::to_string(start.axis.size()) + " axes, the geometry " +
                                std::to_string(g.count) + " components");
  const Nodes nodes = start.nodes(g.pitch);
  const std::size_t last = start.axis.size() - 1;
  ChainState best = start;
  double best_cost = std::numeric_limits<double>::infinity();
  constexpr int kSteps = kSlideCandidates;  // per pitch: the best start is within pitch/16
  // Shifts 0, -1, +1, -2, ... (in pitch/kSteps): a tie (no point near any candidate)
  // keeps the smallest move.
  for (int c = 0; c < kSteps; ++c) {
    const int i = (c % 2 == 0 ? 1 : -1) * ((c + 1) / 2);
    const double shift = g.pitch * i / kSteps;
    // Each node moves along the component it leads into (forward) or out of (backward):
    // on a gently bent chain, very nearly the chain slid along itself.
    Nodes moved = nodes;
    for (std::size_t j = 0; j < nodes.size(); ++j) {
      const std::size_t k = shift >= 0 ? std::min(j, last) : (j == 0 ? 0 : j - 1);
      moved[j] += shift * start.axis[k];
    }
    const ChainState candidate = chain_from_nodes(moved, g);
    const double cost =
        pass(pts, frames_of(candidate, g), candidate, g, params, threads, 1,
             Association{nullptr, false, true})
            .robust;
    if (cost < best_cost) {
      best_cost = cost;
      best = candidate;
    }
  }
  return best;
}

ChainFitResult fit_chain(const PointsView& pts, ChainState& chain,
                         const ComponentGeometry& g, const ChainFitParams& params, int threads,
                         const ChainState* shape, const ChainAnchor* anchor,
                         ChainPassDevice* device, const DepthView* depth) {
  params.validate();
  if (depth != nullptr) depth->validate();
  g.validate();
  const int count = static_cast<int>(chain.axis.size());
  if (count != g.count)
    throw std::invalid_argument("fit_chain: the chain has " + std::to_string(count) +
                                " axes, the geometry " + std::to_string(g.count) + " components");
  if (threads <= 0) threads = omp_get_num_procs();
  if (shape != nullptr && shape->axis.size() != chain.axis.size())
    throw std::invalid_argument("fit_chain: the shape prior has " +
                                std::to_string(shape->axis.size()) + " axes, the chain " +
                                std::to_string(count));
  if (anchor != nullptr &&
      !(anchor->c0.allFinite() && std::abs(anchor->axis0.norm() - 1) < 1e-6 &&
        anchor->sigma_m > 0 && anchor->sigma_rad > 0 && std::isfinite(anchor->sigma_m) &&
        std::isfinite(anchor->sigma_rad)))
    throw std::invalid_argument(
        "fit_chain: the anchor needs a finite c0, a unit axis0 and finite sigmas > 0");
  if (anchor != nullptr) {
    bool held_ok = anchor->held.size() <= static_cast<std::size_t>(count) &&
                   anchor->held_sigma_m > 0 && std::isfinite(anchor->held_sigma_m);
    for (const std::optional<Eigen::Vector3d>& h : anchor->held)
      held_ok = held_ok && (!h || h->allFinite());
    if (!held_ok)
      throw std::invalid_argument(
          "fit_chain: the anchor's held centres must be finite, at most one per component, "
          "with a finite sigma > 0");
  }
  const Eigen::Index n = 3 + 2 * count;
  ChainFitResult result;
  Eigen::MatrixXd H(n, n);
  Eigen::VectorXd b(n);
  // On a device, the association buffers are the device's: `accepted` names the accepted
  // one. On the CPU: the accepted chain's association, and a trial's own when it searches
  // (kept only if the trial is accepted, so a rejected trial leaves the association it
  // was priced against).
  std::vector<std::int16_t> assoc, trial_assoc;
  if (device == nullptr) {
    assoc.resize(pts.size());
    trial_assoc.resize(pts.size());
  }
  int accepted = 0;
  // The free-space rays of the last pass run (depth given).
  int rays = 0;
  // A pass at `c` over every `stride`-th point: reusing the accepted association, or
  // searching into the trial's buffer (`first`: into the accepted one). A coarse pass's
  // sums are scaled by its stride (on the host, so the same bits on every back end), so
  // that the priors, the free-space rays and the held balls, and the inlier thresholds
  // they use, weigh against the points as on a full pass.
  const auto run_pass = [&](const Frames& fr, const ChainState& c, bool reuse, bool first,
                            std::size_t stride) {
    Sums sums = device != nullptr
                    ? device->chain_pass(fr, g, params, !reuse, accepted,
                                         first ? accepted : 1 - accepted, stride)
                    : pass(pts, fr, c, g, params, threads, stride,
                           reuse ? Association{assoc.data(), true}
                                 : Association{first ? assoc.data() : trial_assoc.data(), false});
    if (stride > 1) {
      const auto k = static_cast<double>(stride);
      for (std::size_t j = 0; j < sums.H.size(); ++j) {
        sums.H[j] *= k;
        sums.b[j] *= k;
        sums.count[j] *= static_cast<std::int64_t>(stride);
      }
      sums.robust *= k;
      sums.sum2 *= k;
      sums.inliers *= stride;
    }
    if (depth != nullptr) rays = add_free_space(sums, fr, g, params, *depth);
    if (anchor != nullptr) add_held(sums, fr, params, *anchor);
    return sums;
  };
  // The prior's weight: a bend change of bend_sigma costs what a point at the Huber
  // threshold does.
  const double prior_weight =
      shape ? std::pow(params.huber / params.bend_sigma, 2) : 0.0;
  // The priors' cost at `c`, and their normal equations added to H, b when asked.
  const auto priors = [&](const ChainState& c, const Frames& fr, bool equations) {
    Eigen::MatrixXd* h = equations ? &H : nullptr;
    Eigen::VectorXd* v = equations ? &b : nullptr;
    return (shape ? shape_prior(c, fr, *shape, prior_weight, h, v) : 0.0) +
           (anchor ? anchor_prior(c, fr, *anchor, params.huber, h, v) : 0.0);
  };
  const auto normal_equations = [&](const Sums& s, const ChainState& c, const Frames& fr) {
    assemble(s, fr, g.pitch, H, b);
    return s.robust + priors(c, fr, true);
  };
  // Coarse to fine (ChainFitParams::coarse_stride): stage 0 on every stride-th point, stage
  // 1 on all; without the coarse stage, stage 1 alone.
  const auto stride = static_cast<std::size_t>(params.coarse_stride);
  bool coarse = stride > 1 && pts.size() / stride >= kCoarseMinPerComponent *
                                                          static_cast<std::size_t>(count);
  Frames f = frames_of(chain, g);
  Sums current(0);
  int current_rays = 0;
  for (int stage = coarse ? 0 : 1; stage < 2; ++stage) {
    const std::size_t step_stride = stage == 0 ? stride : 1;
    double lambda = 1e-4;  // damping, relative to the diagonal (Levenberg-Marquardt)
    // One pass per iteration: it linearizes at the chain and gives the chain's cost; a
    // trial that costs more is dropped and the damping raised (one more pass). Each stage
    // starts with a search: the coarse one's association holds its own points only.
    if (stage == 1) f = frames_of(chain, g);
    current = run_pass(f, chain, false, true, step_stride);
    current_rays = rays;
    ++result.searches;
    ++result.passes;
    result.coarse_passes += stage == 0;
    // A component with few coarse points (hidden, or at the image's edge) is where the
    // free-space rays and the held balls switch on and off with the counts, and its coarse
    // estimate is poor: such a chain is fitted on every point from the start, as without
    // the coarse stage (this pass wasted).
    if (stage == 0 &&
        std::any_of(current.count.begin(), current.count.end(), [&](std::int64_t c) {
          return c < static_cast<std::int64_t>(kCoarseMinPerComponent * stride);
        })) {
      coarse = false;
      continue;
    }
    Nodes searched_at = f.centre;  // the nodes where the points were last searched
    double current_cost = normal_equations(current, chain, f);
    for (int it = 0; it < params.max_iterations; ++it) {
      // A parameter nothing constrains (an axis of a hidden component without a shape
      // prior) has a zero row: the floor keeps it where it is.
      Eigen::MatrixXd A = H;
      for (Eigen::Index d = 0; d < n; ++d) A(d, d) += lambda * H(d, d) + 1e-12;
      const Eigen::VectorXd dx = A.ldlt().solve(b);
      ChainState trial = stepped(chain, f, dx);
      limit_bends(trial, params.cone_limit);
      double moved = 0;
      const Nodes after = trial.nodes(g.pitch);
      for (std::size_t k = 0; k < after.size(); ++k)
        moved = std::max(moved, (after[k] - f.centre[k]).norm());
      // A minimum, within the tolerance: the step is taken unchecked (one pass less; it
      // moves next to nothing). After the coarse stage, the full pass's first step is
      // taken unchecked up to coarse_accept: from that near, one step converges. The
      // coarse stage stops within half of that, so that the full step (what is left of the
      // coarse one, plus the offset between the coarse points' minimum and all points')
      // stays within it: a start already at the minimum (a still link) then costs one
      // coarse pass and one full one.
      const double unchecked =
          stage == 0   ? std::max(params.tolerance, 0.5 * params.coarse_accept)
          : it == 0 && coarse ? std::max(params.tolerance, params.coarse_accept)
                              : params.tolerance;
      if (moved <= unchecked) {
        chain = std::move(trial);
        break;
      }
      Frames tf = frames_of(trial, g);
      double drift = 0;
      for (std::size_t k = 0; k < after.size(); ++k)
        drift = std::max(drift, (after[k] - searched_at[k]).norm());
      const bool reuse = drift <= params.reassociate;
      Sums ts = run_pass(tf, trial, reuse, false, step_stride);
      ++result.passes;
      result.coarse_passes += stage == 0;
      result.searches += !reuse;
      const double trial_cost = ts.robust + priors(trial, tf, false);
      if (trial_cost <= current_cost) {
        chain = std::move(trial);
        f = std::move(tf);
        current = std::move(ts);
        current_rays = rays;
        current_cost = normal_equations(current, chain, f);
        lambda = std::max(lambda / 10, 1e-9);
        ++result.iterations;
        if (!reuse) {
          assoc.swap(trial_assoc);
          accepted = 1 - accepted;
          searched_at = after;
        }
      } else {
        lambda *= 10;
        if (lambda > 1e8) break;  // no damped step lowers the cost
      }
    }
  }
  result.inliers = current.inliers;
  result.rms = current.inliers ? std::sqrt(current.sum2 / static_cast<double>(current.inliers)) : 0.0;
  result.cost = current.robust;
  result.free_space_rays = current_rays;
  result.anchor_cost = anchor ? anchor_prior(chain, frames_of(chain, g), *anchor,
                                             params.huber, nullptr, nullptr)
                              : 0.0;
  result.counts = std::move(current.count);
  return result;
}

}  // namespace linksight
