#include "linksight/sim/depth_stats.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <memory>
#include <numbers>
#include <numeric>
#include <stdexcept>
#include <string>
#include <utility>

#include "linksight/sim/sensor.hpp"
#include "linksight/sim/sensor_noise.hpp"
#include "surface_render.hpp"
#include "linksight/tracker/quantile.hpp"

namespace linksight::sim {

namespace {

// The median (linksight::quantile), 0 when there is nothing: a statistic that was not
// measured reads 0. Reorders `v`.
double median_in_place(std::vector<double>& v) { return v.empty() ? 0 : quantile_in_place(v, 0.5); }
double median(std::vector<double> v) { return median_in_place(v); }

// One discontinuity found on a row: widths in px, depths in m.
struct Edge {
  bool near_left;
  int invalid;  // invalid pixels between the two stable sides
  int span;     // every pixel between them (invalid or flying)
  double z_near, z_far;
  bool first_invalid = false, second_invalid = false;  // 1 and 2 px past the near side
};

// Correlation sums at lags 1..4, pooled over windows and both directions; per direction
// at lags 1..kCorrelationLags; and the same per direction by depth bin (`depth_edges`).
struct CorrelationSums {
  std::array<double, 4> ab{}, aa{}, bb{};
  struct Direction {
    std::array<double, kCorrelationLags> ab{}, aa{}, bb{};
    [[nodiscard]] std::array<double, kCorrelationLags> correlation() const {
      std::array<double, kCorrelationLags> c{};
      for (int l = 0; l < kCorrelationLags; ++l)
        c[l] = aa[l] > 0 && bb[l] > 0 ? ab[l] / std::sqrt(aa[l] * bb[l]) : 0;
      return c;
    }
  } rows, cols;
  struct Bin {
    int windows = 0;
    Direction rows, cols;
  };
  std::vector<double> depth_edges;
  std::vector<Bin> by_depth;  // one fewer than depth_edges
  // The bin of a window at median depth z [m], or null outside the edges.
  [[nodiscard]] Bin* bin(double z) {
    const auto it = std::upper_bound(depth_edges.begin(), depth_edges.end(), z);
    if (it == depth_edges.begin() || it == depth_edges.end()) return nullptr;
    return &by_depth[static_cast<std::size_t>(it - depth_edges.begin() - 1)];
  }
};

class Frame {
 public:
  Frame(const io::DepthImage& img, const io::Intrinsics& K, const DepthStatsParams& p)
      : img_(img), K_(K), p_(p), W_(img.width), H_(img.height) {}

  [[nodiscard]] bool valid(int u, int v) const { return img_.data[idx(u, v)] != 0; }
  [[nodiscard]] double z(int u, int v) const { return img_.data[idx(u, v)] * K_.depth_scale; }

  // Plane fits over non-overlapping windows of n x n px, each with at least min_valid
  // valid pixels; the residual correlation into `corr` when given.
  void windows(int n, int min_valid, std::vector<DepthStats::Window>& out,
               CorrelationSums* corr) const {
    std::vector<double> r(static_cast<std::size_t>(n * n));
    std::vector<char> ok(static_cast<std::size_t>(n * n));
    for (int v0 = 0; v0 + n <= H_; v0 += n) {
      for (int u0 = 0; u0 + n <= W_; u0 += n) {
        Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
        Eigen::Vector3d b = Eigen::Vector3d::Zero();
        Eigen::Vector3d mean3 = Eigen::Vector3d::Zero();
        Eigen::Matrix3d cov3 = Eigen::Matrix3d::Zero();
        std::vector<double> zs;
        int count = 0;
        const double uc = u0 + 0.5 * (n - 1), vc = v0 + 0.5 * (n - 1);
        for (int j = 0; j < n; ++j)
          for (int i = 0; i < n; ++i) {
            const bool has = valid(u0 + i, v0 + j);
            ok[static_cast<std::size_t>(j * n + i)] = has;
            if (!has) continue;
            const double zz = z(u0 + i, v0 + j);
            const Eigen::Vector3d x(1.0, u0 + i - uc, v0 + j - vc);
            A += x * x.transpose();
            b += x * zz;
            const Eigen::Vector3d q((u0 + i - K_.cx) / K_.fx * zz, (v0 + j - K_.cy) / K_.fy * zz, zz);
            mean3 += q;
            cov3 += q * q.transpose();
            zs.push_back(zz);
            ++count;
          }
        if (count < min_valid) continue;
        // Axial residuals of z = c0 + c1 du + c2 dv: the noise along the optical axis.
        const Eigen::Vector3d c = A.ldlt().solve(b);
        double ss = 0, worst = 0;
        for (int j = 0; j < n; ++j)
          for (int i = 0; i < n; ++i) {
            const std::size_t k = static_cast<std::size_t>(j * n + i);
            if (!ok[k]) continue;
            r[k] = z(u0 + i, v0 + j) - (c[0] + c[1] * (u0 + i - uc) + c[2] * (v0 + j - vc));
            ss += r[k] * r[k];
            worst = std::max(worst, std::abs(r[k]));
          }
        if (worst > p_.max_residual) continue;  // an edge or a flying pixel, not a surface
        // The correlation is taken on the residuals of a quadratic surface: a plane leaves
        // the curvature of real surfaces (clothing, skin), which would read as correlation.
        Eigen::Matrix<double, 6, 6> Q = Eigen::Matrix<double, 6, 6>::Zero();
        Eigen::Matrix<double, 6, 1> qb = Eigen::Matrix<double, 6, 1>::Zero();
        auto basis = [&](int i, int j) {
          const double x = (i - 0.5 * (n - 1)) / n, y = (j - 0.5 * (n - 1)) / n;
          Eigen::Matrix<double, 6, 1> e;
          e << 1.0, x, y, x * x, x * y, y * y;
          return e;
        };
        for (int j = 0; j < n; ++j)
          for (int i = 0; i < n; ++i) {
            if (!ok[static_cast<std::size_t>(j * n + i)]) continue;
            const Eigen::Matrix<double, 6, 1> e = basis(i, j);
            Q += e * e.transpose();
            qb += e * z(u0 + i, v0 + j);
          }
        const Eigen::Matrix<double, 6, 1> qc = Q.ldlt().solve(qb);
        double ss_quad = 0;
        for (int j = 0; j < n; ++j)
          for (int i = 0; i < n; ++i) {
            const std::size_t k = static_cast<std::size_t>(j * n + i);
            if (!ok[k]) continue;
            r[k] = z(u0 + i, v0 + j) - basis(i, j).dot(qc);
            ss_quad += r[k] * r[k];
          }
        mean3 /= count;
        cov3 = cov3 / count - mean3 * mean3.transpose();
        const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov3);
        const Eigen::Vector3d normal = es.eigenvectors().col(0);  // smallest eigenvalue
        const double cos_t = std::abs(normal.dot(mean3.normalized()));
        out.push_back({median(zs), std::acos(std::min(1.0, cos_t)), std::sqrt(ss / (count - 3)),
                       // (a window of 6 px or fewer has no quadratic residual: its plane's)
                       count > 6 ? std::sqrt(ss_quad / (count - 6)) : std::sqrt(ss / (count - 3))});
        // Correlation on windows seen nearly face-on only: on a slanted surface the lateral
        // noise adds depth noise of its own, white, which would dilute the reading.
        if (corr == nullptr || out.back().angle >= p_.depth_bin_max_angle) continue;
        CorrelationSums::Bin* at_depth = corr->bin(out.back().z);
        if (at_depth != nullptr) ++at_depth->windows;
        for (int lag = 1; lag <= kCorrelationLags && lag < n; ++lag)
          for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
              const std::size_t k = static_cast<std::size_t>(j * n + i);
              if (!ok[k]) continue;
              const auto add = [&](std::size_t k2, CorrelationSums::Direction& d,
                                   CorrelationSums::Direction* d_at_depth) {
                if (!ok[k2]) return;
                const double ab = r[k] * r[k2], aa = r[k] * r[k], bb = r[k2] * r[k2];
                for (CorrelationSums::Direction* e : {&d, d_at_depth}) {
                  if (e == nullptr) continue;
                  e->ab[lag - 1] += ab;
                  e->aa[lag - 1] += aa;
                  e->bb[lag - 1] += bb;
                }
                if (lag > 4) return;
                corr->ab[lag - 1] += ab;
                corr->aa[lag - 1] += aa;
                corr->bb[lag - 1] += bb;
              };
              if (i + lag < n)
                add(k + static_cast<std::size_t>(lag), corr->rows,
                    at_depth != nullptr ? &at_depth->rows : nullptr);
              if (j + lag < n)
                add(k + static_cast<std::size_t>(lag * n), corr->cols,
                    at_depth != nullptr ? &at_depth->cols : nullptr);
            }
      }
    }
  }

  // Discontinuities along rows, between two stable valid pixels (each with a valid
  // neighbour on its outer side within a quarter of the jump).
  void edges(std::vector<Edge>& out, long& flying, long& lone, long& neighbours,
             std::vector<double>& positions, long& side_pixels, long& side_flying) const {
    std::vector<int> beside;  // this discontinuity's pixels beside its invalid runs
    const double calm = 0.25 * p_.edge_jump;
    for (int v = 0; v < H_; ++v) {
      int u = 1;
      while (u < W_ - 2) {
        // A: the last pixel of a stable surface before something else starts.
        const bool a_stable = valid(u, v) && valid(u - 1, v) && std::abs(z(u, v) - z(u - 1, v)) < calm;
        const bool a_ends = !valid(u + 1, v) || std::abs(z(u + 1, v) - z(u, v)) >= calm;
        if (!(a_stable && a_ends)) {
          ++u;
          continue;
        }
        int b = -1;
        for (int w = u + 1; w < W_ - 1 && w <= u + p_.max_band_px + 1; ++w) {
          if (valid(w, v) && valid(w + 1, v) && std::abs(z(w + 1, v) - z(w, v)) < calm) {
            b = w;
            break;
          }
        }
        if (b < 0) {
          ++u;
          continue;
        }
        const double za = z(u, v), zb = z(b, v);
        if (std::abs(zb - za) > p_.edge_jump) {
          Edge e{za < zb, 0, b - u - 1, std::min(za, zb), std::max(za, zb)};
          // Counted from the near side's last stable pixel toward the far side.
          const int step = e.near_left ? 1 : -1, from = e.near_left ? u : b;
          e.first_invalid = !valid(from + step, v);
          e.second_invalid = b - u >= 3 && !valid(from + 2 * step, v);
          long here_valid = 2;  // A and B
          int between = 0;
          for (int w = u + 1; w < b; ++w) {
            if (!valid(w, v)) {
              ++e.invalid;
              continue;
            }
            ++here_valid;
            const double pos = (z(w, v) - e.z_near) / (e.z_far - e.z_near);
            if (pos > 0.1 && pos < 0.9) {
              ++flying;
              ++between;
              positions.push_back(pos);
            }
          }
          // A lone pixel in the gap: what a flying pixel makes. A side face seen at grazing
          // incidence leaves a run of them instead.
          if (between == 1) ++lone;
          // Beside the bands (DepthStats::band_side_pixels): the valid pixels within 2 px
          // of each invalid run, from A - 1 to B + 1 (both stable sides' pixels are valid).
          beside.clear();
          for (int w = u + 1; w < b; ++w) {
            if (valid(w, v) || (w > u + 1 && !valid(w - 1, v))) continue;  // a run's start
            int end = w;
            while (end + 1 < b && !valid(end + 1, v)) ++end;
            for (const int x : {w - 2, w - 1, end + 1, end + 2})
              if (x >= u - 1 && x <= b + 1 && valid(x, v)) beside.push_back(x);
          }
          std::sort(beside.begin(), beside.end());
          beside.erase(std::unique(beside.begin(), beside.end()), beside.end());
          side_pixels += static_cast<long>(beside.size());
          for (const int x : beside) {
            if (x <= u || x >= b) continue;  // a stable side: not between them
            const double pos = (z(x, v) - e.z_near) / (e.z_far - e.z_near);
            if (pos > 0.1 && pos < 0.9) ++side_flying;
          }
          if (e.invalid > 0 || b == u + 1) neighbours += here_valid;
          out.push_back(e);
        }
        u = b;
      }
    }
  }

  // Interior holes: invalid 4-connected regions with nothing else invalid within 2 px
  // (not touching the border, a band or another hole: jitter leaves stray pixels along
  // shadow edges), enclosed by valid pixels of one surface (their depths within the edge
  // jump). With `within`, a hole counts only if every pixel of it and within 2 px of it is
  // set there (so that the other frame could have counted a hole there by the same rule);
  // `mark` gets every counted hole's pixels set.
  void holes(std::vector<int>& sizes, const std::vector<std::uint8_t>* within = nullptr,
             std::vector<std::uint8_t>* mark = nullptr) const {
    std::vector<int> comp(img_.data.size(), -1);
    std::vector<int> stack, members;
    int id = 0;
    for (int v0 = 0; v0 < H_; ++v0)
      for (int u0 = 0; u0 < W_; ++u0) {
        if (valid(u0, v0) || comp[idx(u0, v0)] >= 0) continue;
        bool isolated = true;
        double lo = 1e9, hi = -1e9;
        members.clear();
        stack.assign(1, static_cast<int>(idx(u0, v0)));
        comp[idx(u0, v0)] = id;
        while (!stack.empty()) {
          const int k = stack.back();
          stack.pop_back();
          members.push_back(k);
          const int u = k % W_, v = k / W_;
          const int du[4] = {1, -1, 0, 0}, dv[4] = {0, 0, 1, -1};
          for (int d = 0; d < 4; ++d) {
            const int uu = u + du[d], vv = v + dv[d];
            if (uu < 0 || vv < 0 || uu >= W_ || vv >= H_) continue;
            const std::size_t kk = idx(uu, vv);
            if (valid(uu, vv)) {
              lo = std::min(lo, z(uu, vv));
              hi = std::max(hi, z(uu, vv));
            } else if (comp[kk] < 0) {
              comp[kk] = id;
              stack.push_back(static_cast<int>(kk));
            }
          }
        }
        const int size = static_cast<int>(members.size());
        for (std::size_t i = 0; i < members.size() && isolated && size <= p_.max_hole_px; ++i) {
          const int u = members[i] % W_, v = members[i] / W_;
          for (int dv = -2; dv <= 2 && isolated; ++dv)
            for (int du = -2; du <= 2 && isolated; ++du) {
              const int uu = u + du, vv = v + dv;
              isolated = uu >= 0 && vv >= 0 && uu < W_ && vv < H_ &&
                         (valid(uu, vv) || comp[idx(uu, vv)] == id) &&
                         (within == nullptr || (*within)[idx(uu, vv)] != 0);
            }
        }
        ++id;
        if (!isolated || size > p_.max_hole_px || hi - lo > p_.edge_jump) continue;
        sizes.push_back(size);
        if (mark)
          for (const int k : members) (*mark)[static_cast<std::size_t>(k)] = 1;
      }
  }

 private:
  [[nodiscard]] std::size_t idx(int u, int v) const {
    return static_cast<std::size_t>(v) * static_cast<std::size_t>(W_) + static_cast<std::size_t>(u);
  }
  const io::DepthImage& img_;
  const io::Intrinsics& K_;
  const DepthStatsParams& p_;
  int W_, H_;
};

// Least-squares line y = slope x + intercept over the points with keep[i]; returns r.
double fit_line(const std::vector<double>& x, const std::vector<double>& y,
                const std::vector<char>& keep, double& slope, double& intercept) {
  double n = 0, sx = 0, sy = 0, sxx = 0, sxy = 0, syy = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (!keep[i]) continue;
    n += 1, sx += x[i], sy += y[i], sxx += x[i] * x[i], sxy += x[i] * y[i], syy += y[i] * y[i];
  }
  if (n < 2) return 0;
  const double vx = sxx - sx * sx / n, vy = syy - sy * sy / n, cxy = sxy - sx * sy / n;
  if (!(vx > 0)) return 0;
  slope = cxy / vx;
  intercept = (sy - slope * sx) / n;
  return vy > 0 ? cxy / std::sqrt(vx * vy) : 0;
}

EdgeSide side_of(const std::vector<Edge>& edges, bool near_left, double f) {
  EdgeSide s;
  std::vector<double> widths, x, y;
  int one = 0, two = 0;
  for (const Edge& e : edges) {
    if (e.near_left != near_left) continue;
    ++s.edges;
    s.direct += e.invalid == 0;
    one += e.first_invalid;
    two += e.second_invalid;
    widths.push_back(e.invalid);
    x.push_back(f * (1.0 / e.z_near - 1.0 / e.z_far));
    y.push_back(e.span);
  }
  s.gap_px = x;
  s.width_px = y;
  if (s.edges == 0) return s;
  const double n = s.edges;
  s.invalid_1px = one / n;
  s.invalid_2px = two / n;
  s.band_median_px = median(widths);
  // Shadows cut short (a narrow caster, a shadow landing on a third surface, an object's
  // top or bottom corner) lie below the line: fit, drop points beyond 3 robust sigmas,
  // fit again.
  std::vector<char> keep(x.size(), 1);
  s.fit_r = fit_line(x, y, keep, s.slope, s.intercept);
  std::vector<double> res(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) res[i] = std::abs(y[i] - s.slope * x[i] - s.intercept);
  const double mad = median(res);
  if (mad > 0) {
    for (std::size_t i = 0; i < x.size(); ++i) keep[i] = res[i] <= 3.0 * 1.4826 * mad;
    s.fit_r = fit_line(x, y, keep, s.slope, s.intercept);
  }
  return s;
}

}  // namespace

void DepthStatsParams::validate() const {
  auto bad = [](const std::string& field, const std::string& rule) {
    throw std::invalid_argument("DepthStatsParams." + field + ": " + rule);
  };
  if (window < 5) bad("window", "must be >= 5 px");
  if (min_valid < 4 || min_valid > window * window) bad("min_valid", "must be in [4, window^2]");
  if (!(max_residual > 0)) bad("max_residual", "must be > 0 m");
  if (!(edge_jump > 0)) bad("edge_jump", "must be > 0 m");
  if (max_band_px < 1) bad("max_band_px", "must be >= 1");
  if (max_hole_px < 1) bad("max_hole_px", "must be >= 1");
  for (const int n : scale_windows)
    if (n < 5) bad("scale_windows", "each must be >= 5 px");
  if (!(neighbour_jump > 0)) bad("neighbour_jump", "must be > 0 m");
  for (const auto* e : {&depth_edges, &angle_edges}) {
    if (e->size() < 2 || !std::is_sorted(e->begin(), e->end()) ||
        std::adjacent_find(e->begin(), e->end()) != e->end())
      bad(e == &depth_edges ? "depth_edges" : "angle_edges", "need >= 2 increasing edges");
  }
}

DepthStats depth_stats(const std::vector<io::DepthImage>& frames, const io::Intrinsics& K,
                       const DepthStatsParams& p, const std::vector<io::DepthImage>* seen) {
  p.validate();
  if (frames.empty()) throw std::invalid_argument("depth statistics: no frames");
  // Where each seen frame shows a surface: its valid pixels and its own interior holes.
  std::vector<std::vector<std::uint8_t>> surface_seen;
  if (seen) {
    if (seen->empty()) throw std::invalid_argument("depth statistics: no seen frame");
    if (frames.size() % seen->size() != 0)
      throw std::invalid_argument("depth statistics: " + std::to_string(frames.size()) +
                                  " images are not a whole number of draws of " +
                                  std::to_string(seen->size()) + " seen frames");
    for (std::size_t f = 0; f < seen->size(); ++f) {
      const io::DepthImage& img = (*seen)[f];
      if (img.width != K.width || img.height != K.height)
        throw std::invalid_argument("seen frame " + std::to_string(f) + " is " +
                                    std::to_string(img.width) + "x" + std::to_string(img.height) +
                                    ", the intrinsics say " + std::to_string(K.width) + "x" +
                                    std::to_string(K.height));
      std::vector<std::uint8_t>& mask = surface_seen.emplace_back(img.data.size());
      for (std::size_t i = 0; i < mask.size(); ++i) mask[i] = img.data[i] != 0;
      std::vector<int> unused;
      Frame(img, K, p).holes(unused, nullptr, &mask);
    }
  }
  DepthStats s;
  s.frames = static_cast<int>(frames.size());
  s.window = p.window;
  s.depth_bin_max_angle = p.depth_bin_max_angle;
  s.neighbour_jump = p.neighbour_jump;
  CorrelationSums corr;
  corr.depth_edges = p.depth_edges;
  corr.by_depth.resize(p.depth_edges.size() - 1);
  std::vector<std::vector<DepthStats::Window>> scale_samples(p.scale_windows.size());
  std::vector<Edge> edges;
  long flying = 0, lone = 0;
  std::vector<double> positions;
  std::array<long, 256> diffs{};
  for (std::size_t f = 0; f < frames.size(); ++f) {
    const io::DepthImage& img = frames[f];
    if (img.width != K.width || img.height != K.height)
      throw std::invalid_argument("frame " + std::to_string(f) + " is " +
                                  std::to_string(img.width) + "x" + std::to_string(img.height) +
                                  ", the intrinsics say " + std::to_string(K.width) + "x" +
                                  std::to_string(K.height));
    const Frame fr(img, K, p);
    for (std::uint16_t d : img.data) s.valid_px += d != 0;
    // Neighbour differences of raw values, for the quantization step (along rows), and
    // the jumps between valid neighbours (rows and columns).
    const auto raw = [&](int u, int v) {
      return static_cast<int>(img.data[static_cast<std::size_t>(v) * img.width + u]);
    };
    const auto pair = [&](int a, int b) {
      if (!a || !b) return;
      ++s.neighbour_pairs;
      s.neighbour_jumps += std::abs(a - b) * K.depth_scale > p.neighbour_jump;
    };
    for (int v = 0; v < img.height; ++v)
      for (int u = 0; u < img.width; ++u) {
        const int a = raw(u, v);
        if (v + 1 < img.height) pair(a, raw(u, v + 1));
        if (u + 1 >= img.width) continue;
        const int b = raw(u + 1, v);
        pair(a, b);
        const int d = std::abs(a - b);
        if (a && b && d > 0 && d < 256) ++diffs[static_cast<std::size_t>(d)];
      }
    fr.windows(p.window, p.min_valid, s.samples, &corr);
    for (std::size_t w = 0; w < p.scale_windows.size(); ++w) {
      const int n = p.scale_windows[w];
      if (n == p.window) continue;  // the samples above
      // min_valid in proportion to the area, and enough for a quadratic's 6 parameters.
      const int min_valid = std::max(7, static_cast<int>(std::ceil(
          static_cast<double>(p.min_valid) * n * n / (static_cast<double>(p.window) * p.window))));
      fr.windows(n, min_valid, scale_samples[w], nullptr);
    }
    fr.edges(edges, flying, lone, s.band_neighbours, positions, s.band_side_pixels,
             s.band_side_flying);
    fr.holes(s.hole_sizes, seen ? &surface_seen[f % seen->size()] : nullptr);
  }
  if (s.valid_px == 0) throw std::invalid_argument("depth statistics: no valid pixel in any frame");
  s.windows = static_cast<int>(s.samples.size());
  if (s.windows < 10)
    throw std::invalid_argument("depth statistics: " + std::to_string(s.windows) +
                                " flat windows of " + std::to_string(p.window) + "x" +
                                std::to_string(p.window) +
                                " px; need at least 10 to estimate the noise (a recording too "
                                "small, or without smooth surfaces)");

  // Quantization: the gcd of the differences that are common (>= 0.5% of them).
  const long total = std::accumulate(diffs.begin(), diffs.end(), 0L);
  int step = 0;
  for (int d = 1; d < 256; ++d)
    if (diffs[static_cast<std::size_t>(d)] * 200 >= total) step = std::gcd(step, d);
  s.depth_step = std::max(step, 1) * K.depth_scale;

  auto bins = [&](const std::vector<double>& edges_, bool by_depth,
                  double DepthStats::Window::*sigma = &DepthStats::Window::sigma) {
    std::vector<SigmaBin> out;
    for (std::size_t b = 0; b + 1 < edges_.size(); ++b) {
      SigmaBin bin;
      bin.lo = edges_[b];
      bin.hi = edges_[b + 1];
      std::vector<double> sig, at;
      for (const DepthStats::Window& w : s.samples) {
        if (!in_sigma_bin(w, bin, by_depth, p.depth_bin_max_angle)) continue;
        sig.push_back(w.*sigma);
        at.push_back(by_depth ? w.z : w.angle);
      }
      bin.windows = static_cast<int>(sig.size());
      bin.sigma = median(sig);
      bin.centre = median(at);
      out.push_back(bin);
    }
    return out;
  };
  s.sigma_by_depth = bins(p.depth_edges, true);
  s.sigma_by_angle = bins(p.angle_edges, false);
  s.sigma_quad_by_angle = bins(p.angle_edges, false, &DepthStats::Window::sigma_quad);
  s.sigma_quad_by_depth = bins(p.depth_edges, true, &DepthStats::Window::sigma_quad);
  for (int l = 0; l < 4; ++l)
    s.correlation[static_cast<std::size_t>(l)] =
        corr.aa[l] > 0 && corr.bb[l] > 0 ? corr.ab[l] / std::sqrt(corr.aa[l] * corr.bb[l]) : 0;
  s.correlation_rows = corr.rows.correlation();
  s.correlation_cols = corr.cols.correlation();
  for (std::size_t b = 0; b < corr.by_depth.size(); ++b)
    s.correlation_by_depth.push_back({p.depth_edges[b], p.depth_edges[b + 1],
                                      corr.by_depth[b].windows, corr.by_depth[b].rows.correlation(),
                                      corr.by_depth[b].cols.correlation()});
  const auto scale_of = [](int window, const std::vector<DepthStats::Window>& ws) {
    DepthStats::Scale sc;
    sc.window = window;
    sc.windows = static_cast<int>(ws.size());
    std::vector<double> plane, quad;
    int beats = 0;
    for (const DepthStats::Window& w : ws) {
      plane.push_back(w.sigma);
      quad.push_back(w.sigma_quad);
      beats += w.sigma_quad < kQuadBeatsPlane * w.sigma;
    }
    sc.sigma = median(plane);
    sc.sigma_quad = median(quad);
    sc.quad_beats_plane = ws.empty() ? 0 : static_cast<double>(beats) / static_cast<double>(ws.size());
    return sc;
  };
  const DepthStats::Scale at_window = scale_of(p.window, s.samples);
  s.quad_beats_plane = at_window.quad_beats_plane;
  for (std::size_t w = 0; w < p.scale_windows.size(); ++w) {
    const int n = p.scale_windows[w];
    s.scales.push_back(n == p.window ? at_window : scale_of(n, scale_samples[w]));
  }

  s.near_left = side_of(edges, true, K.fx);
  s.near_right = side_of(edges, false, K.fx);
  // The shadow side: its band widths grow with the disparity gap; the other side's do not.
  // Near surface left of the gap -> shadow on its image-right -> projector image-left.
  const EdgeSide& l = s.near_left;
  const EdgeSide& r = s.near_right;
  constexpr int kMinEdges = 20;
  constexpr double kMinSlope = 0.005;  // [m]: below 5 mm no baseline is seen
  // Two signs of the shadow side, either of which decides it unless the other side shows
  // one too: the shadow always leaves a band there, so valid pixels jump straight across
  // a gap at most half as often as on the other side; and its band widths follow the gap
  // (fit_r), the other side's much less. Either way its widths must grow with the gap.
  // (Slope and width alone do not decide it: the other side's bands can widen with the
  // gap too, where a side face seen at grazing incidence drops; and where many gaps are
  // narrower than a pixel of shadow, the direct jumps of both sides are alike.)
  constexpr double kMinFitR = 0.3;
  auto direct = [](const EdgeSide& e) { return e.edges ? double(e.direct) / e.edges : 1.0; };
  auto shadow_side = [&](const EdgeSide& a, const EdgeSide& other) {
    const bool follows = a.edges >= kMinEdges && a.slope > kMinSlope && a.fit_r >= kMinFitR;
    const bool fewer_direct = direct(a) < 0.5 * direct(other);  // strict: 0 vs 0 decides nothing
    const bool fits_better = a.fit_r >= 0.5 && other.fit_r < 0.5 * a.fit_r;
    return follows && (fewer_direct || fits_better);
  };
  const bool left = shadow_side(l, r), right = shadow_side(r, l);
  if (left && !right) {
    s.projector_side = -1;
    s.baseline = -l.slope;
  } else if (right && !left) {
    s.projector_side = +1;
    s.baseline = r.slope;
  }
  s.flying = flying;
  s.flying_rate = s.band_neighbours > 0 ? static_cast<double>(flying) / s.band_neighbours : 0;
  s.flying_band_rate = s.band_side_pixels > 0 ? static_cast<double>(s.band_side_flying) /
                                                    static_cast<double>(s.band_side_pixels)
                                              : 0;
  s.flying_position = median(positions);
  s.flying_iqr = positions.empty() ? 0 : quantile(positions, 0.75) - quantile(positions, 0.25);
  const int crossings = s.near_left.edges + s.near_right.edges;
  s.flying_per_edge = crossings > 0 ? static_cast<double>(lone) / crossings : 0;
  s.pixels = static_cast<long>(K.width) * K.height * s.frames;
  s.holes_per_frame = static_cast<double>(s.hole_sizes.size()) / s.frames;
  return s;
}

namespace {

// The residual maker I - X (X^T X)^-1 X^T of a least-squares fit of the first `terms` of
// {1, x, y, x^2, xy, y^2} over an n x n window (pixel a at u = a % n, v = a / n).
Eigen::MatrixXd residual_maker(int n, int terms) {
  const int N = n * n;
  Eigen::MatrixXd X(N, terms);
  for (int a = 0; a < N; ++a) {
    const double x = (a % n - 0.5 * (n - 1)) / n, y = (a / n - 0.5 * (n - 1)) / n;
    const double all[6] = {1.0, x, y, x * x, x * y, y * y};
    for (int t = 0; t < terms; ++t) X(a, t) = all[t];
  }
  const Eigen::MatrixXd H = X * (X.transpose() * X).ldlt().solve(X.transpose());
  return Eigen::MatrixXd::Identity(N, N) - H;
}

// What the window estimator reads of one unit-variance field, as sums linear in the
// field's covariance C, so that fields add by their shares: trace(C P) and trace(C Q)
// (P, Q the plane's and the quadratic's residual makers: symmetric and idempotent, so
// E|P x|^2 = trace(P C P) = trace(C P)), and the correlation sums of Q C Q summed as
// depth_stats sums them (pooled over both directions at lags 1..4; along rows and along
// columns at lags 1..kCorrelationLags).
struct FieldSums {
  double plane = 0, quad = 0;
  std::array<double, 4> ab{}, aa{}, bb{};
  std::array<double, kCorrelationLags> ab_r{}, aa_r{}, bb_r{}, ab_c{}, aa_c{}, bb_c{};
  void add(const FieldSums& o, double w) {
    plane += w * o.plane, quad += w * o.quad;
    for (int l = 0; l < 4; ++l) ab[l] += w * o.ab[l], aa[l] += w * o.aa[l], bb[l] += w * o.bb[l];
    for (int l = 0; l < kCorrelationLags; ++l) {
      ab_r[l] += w * o.ab_r[l], aa_r[l] += w * o.aa_r[l], bb_r[l] += w * o.bb_r[l];
      ab_c[l] += w * o.ab_c[l], aa_c[l] += w * o.aa_c[l], bb_c[l] += w * o.bb_c[l];
    }
  }
};

// The residual makers of one window side, made once per fit.
struct WindowModel {
  int n;
  Eigen::MatrixXd P, Q;
  explicit WindowModel(int side) : n(side), P(residual_maker(side, 3)), Q(residual_maker(side, 6)) {}

  // One field: Gaussian-blurred white noise of widths w_u (along rows), w_v (along
  // columns) correlates pixels du, dv apart by exp(-du^2 / (4 w_u^2)) exp(-dv^2 / (4 w_v^2));
  // 0 is white. A Matern-5/2 field of ranges w_u, w_v by the product of
  // (1 + sqrt(5) d / w + 5 d^2 / (3 w^2)) exp(-sqrt(5) d / w) (AxialKernel). The covariance
  // is the Kronecker product Cv (x) Cu: C M for a window-shaped M is Cu M Cv (n^3 per column
  // instead of n^4), and trace(C M) sums n x n blocks. Without `correlations`, only the
  // traces.
  [[nodiscard]] FieldSums sums(double w_u, double w_v, bool correlations = true,
                               AxialKernel shape = AxialKernel::gaussian) const {
    const int N = n * n;
    auto kernel = [&](double w) {
      Eigen::MatrixXd K = Eigen::MatrixXd::Identity(n, n);
      if (w > 0)
        for (int i = 0; i < n; ++i)
          for (int j = 0; j < n; ++j) {
            const double d = std::abs(i - j), x = std::sqrt(5.0) * d / w;
            K(i, j) = shape == AxialKernel::matern52 ? (1 + x + x * x / 3) * std::exp(-x)
                                                     : std::exp(-d * d / (4 * w * w));
          }
      return K;
    };
    const Eigen::MatrixXd Cu = kernel(w_u), Cv = kernel(w_v);
    auto trace_C = [&](const Eigen::MatrixXd& M) {  // trace(C M) = sum of C o M (symmetric)
      double t = 0;
      for (int vb = 0; vb < n; ++vb)
        for (int va = 0; va < n; ++va)
          t += Cv(va, vb) * Cu.cwiseProduct(M.block(va * n, vb * n, n, n)).sum();
      return t;
    };
    FieldSums f;
    f.plane = trace_C(P);
    f.quad = trace_C(Q);
    if (!correlations) return f;
    Eigen::MatrixXd CQ(N, N);
    for (int b = 0; b < N; ++b) {
      const Eigen::Map<const Eigen::MatrixXd> m(Q.col(b).data(), n, n);
      Eigen::Map<Eigen::MatrixXd>(CQ.col(b).data(), n, n) = Cu * m * Cv;
    }
    auto R = [&](int a, int b) { return Q.col(a).dot(CQ.col(b)); };  // Cov of Q x
    Eigen::VectorXd diag(N);
    for (int a = 0; a < N; ++a) diag[a] = R(a, a);
    for (int lag = 1; lag <= kCorrelationLags && lag < n; ++lag) {
      const auto l = static_cast<std::size_t>(lag - 1);
      for (int a = 0; a < N; ++a) {
        const int u = a % n, v = a / n;
        if (u + lag < n) {
          const double x = R(a, a + lag);
          f.ab_r[l] += x, f.aa_r[l] += diag[a], f.bb_r[l] += diag[a + lag];
        }
        if (v + lag < n) {
          const double x = R(a, a + lag * n);
          f.ab_c[l] += x, f.aa_c[l] += diag[a], f.bb_c[l] += diag[a + lag * n];
        }
      }
      if (lag <= 4) {
        f.ab[l] = f.ab_r[l] + f.ab_c[l];
        f.aa[l] = f.aa_r[l] + f.aa_c[l];
        f.bb[l] = f.bb_r[l] + f.bb_c[l];
      }
    }
    return f;
  }

  [[nodiscard]] WindowResponse response(const FieldSums& f) const {
    const int N = n * n;
    WindowResponse r;
    r.variance_factor = f.plane / (N - 3);
    r.quad_variance_factor = f.quad / (N - 6);
    auto rho = [](double ab, double aa, double bb) { return aa > 0 && bb > 0 ? ab / std::sqrt(aa * bb) : 0.0; };
    for (int l = 0; l < kCorrelationLags && l + 1 < n; ++l) {
      r.correlation_rows[l] = rho(f.ab_r[l], f.aa_r[l], f.bb_r[l]);
      r.correlation_cols[l] = rho(f.ab_c[l], f.aa_c[l], f.bb_c[l]);
      if (l < 4) r.correlation[l] = rho(f.ab[l], f.aa[l], f.bb[l]);
    }
    return r;
  }

  // The two fields of `axial` by their shares.
  [[nodiscard]] FieldSums sums(const AxialNoise& axial) const {
    const double s = axial.low_share;
    FieldSums f;
    f.add(sums(axial.rows_px(), axial.cols_px(), true, axial.kernel), 1 - s);
    if (s > 0) f.add(sums(axial.low_rows_px, axial.low_cols_px), s);
    return f;
  }
};

}  // namespace

WindowResponse window_response(double correlation_px, int window) {
  AxialNoise axial;
  axial.correlation_px = correlation_px;
  axial.correlation_cols_px = 0;
  axial.low_share = 0;
  return window_response(axial, window);
}

WindowResponse window_response(const AxialNoise& axial, int window) {
  if (window < 5)
    throw std::invalid_argument("window_response: window = " + std::to_string(window) +
                                ": must be >= 5 px");
  fields::check(axial, "axial");  // the scene's ranges: widths > 0, low_share < 1
  const WindowModel m(window);
  return m.response(m.sums(axial));
}

AxialReading::AxialReading(const AxialNoise& axial, int window) : axial_(axial) {
  mix_ = window_response(axial, window).variance_factor;
  AxialNoise pixel = axial;
  pixel.low_share = 0;
  pixel_ = window_response(pixel, window).variance_factor;
}

double AxialReading::sigma(double z, double theta) const {
  const AxialNoise::Point p = axial_.point(z, theta);
  const double s = axial_.sigma(p);
  if (axial_.low_angle_term || !(axial_.low_share > 0)) return std::sqrt(mix_) * s;
  const double base = axial_.base(p), t = s - base;
  // mix_ reads the two fields at their shares; the power moves the pixel-scale one's.
  const double r = axial_.pixel_depth_factor(z);
  return std::sqrt(base * base * (mix_ + (1 - axial_.low_share) * pixel_ * (r * r - 1)) +
                   t * t * pixel_);
}

SurfaceRender render_surface(const io::DepthImage& depth, const io::Intrinsics& K,
                             const NoiseParams& noise, std::uint64_t seed, std::uint64_t frame,
                             const DepthSurfaceParams& surface) {
  BackgroundObject b;
  b.shape.kind = Shape::Kind::mesh;
  b.shape.mesh_data = std::make_shared<const TriangleMesh>(depth_surface_mesh(depth, K, surface));
  SensorParams p;
  p.camera = surface_camera(K);
  p.noise = noise;
  const ComponentGeometry g;
  SurfaceRender out;
  out.sensor = std::make_unique<Sensor>(p, g, std::vector<Occluder>{}, std::vector<BackgroundObject>{b});
  // The link out of the way, behind the camera.
  std::vector<Eigen::Isometry3d> X(static_cast<std::size_t>(g.count), Eigen::Isometry3d::Identity());
  for (Eigen::Isometry3d& x : X) x.translation() = Eigen::Vector3d(0, 0, -5);
  out.sensor->render(X, 0.0, seed, frame, out.frame);
  return out;
}

std::vector<io::DepthImage> rerender_surfaces(const std::vector<io::DepthImage>& frames,
                                              const io::Intrinsics& K, const NoiseParams& noise,
                                              std::uint64_t seed, int draws,
                                              const DepthSurfaceParams& surface) {
  if (draws < 1)
    throw std::invalid_argument("rerender_surfaces: draws = " + std::to_string(draws) +
                                ": must be >= 1");
  const std::size_t n = frames.size();
  std::vector<io::DepthImage> out(n * static_cast<std::size_t>(draws));
  SensorNoise redraw(noise, surface_camera(K));
  std::vector<float> depth_m;
  for (std::size_t f = 0; f < n; ++f) {
    SurfaceRender r = render_surface(frames[f], K, noise, seed, f, surface);
    // Further draws re-apply the noise to this render's cast, as fit_noise_rerendered does
    // (the sensor's own render is SensorNoise::apply on it), so both read the same images.
    const NoiseInput in = r.sensor->last_noise_input(r.frame);
    for (std::size_t d = 1; d < static_cast<std::size_t>(draws); ++d) {
      const std::size_t k = draw_index(n, d, f);
      redraw.apply(in, seed, k, 0, out[k], depth_m);
    }
    out[draw_index(n, 0, f)] = std::move(r.frame.depth);
  }
  return out;
}

namespace {

// Median plane-fit and quadratic-fit sigma of the windows the correlation is read on
// (under the depth bins' angle limit) [m].
std::pair<double, double> flat_sigmas(const DepthStats& s) {
  std::vector<double> p, q;
  for (const DepthStats::Window& w : s.samples)
    if (w.angle < s.depth_bin_max_angle) p.push_back(w.sigma), q.push_back(w.sigma_quad);
  return {median(p), median(q)};
}

// The two-term structure of the axial field (AxialNoise: a pixel-scale field of widths
// correlation_px / correlation_cols_px, a low-frequency one of low_rows_px / low_cols_px
// taking low_share of the variance) that the window estimators read as `s` does, in least
// squares over: the residual correlation along rows and along columns at lags
// 1..kCorrelationLags; the quadratic fit's variance over the plane fit's (how much of the
// noise a quadratic takes up); and, at each other window side of s.scales, the plane and
// quadratic variance over those at s.window (how the noise grows with the window: what pins
// the low field's widths, which the correlation in one window hardly sees). `shape`'s
// sigmas are taken out of the variances in quadrature. The pixel-scale field has ax.kernel's
// shape; a Matern (ranges 3-20 px, never white) is fitted alone, without the low field.
// The sums are linear in the
// covariance, so each field's are computed once per pair of widths on a grid and every
// share is a weighted sum of them; a pattern search refines the grid's best. Writes the
// fitted terms into `ax`; returns the response of the fitted field at s.window.
WindowResponse fit_structure(const DepthStats& s, const DepthStats* shape, AxialNoise& ax,
                             std::vector<std::string>& notes) {
  auto less_shape = [](double x, double shape_x) {
    return std::sqrt(std::max(x * x - shape_x * shape_x, 0.01 * x * x));
  };
  auto [plane, quad] = flat_sigmas(s);
  if (shape != nullptr) {
    const auto [sp, sq] = flat_sigmas(*shape);
    plane = less_shape(plane, sp);
    quad = less_shape(quad, sq);
  }
  const double ratio = plane > 0 ? std::min(1.0, quad * quad / (plane * plane)) : 1.0;
  // The other window sides with 20 windows or more, and what they read against s.window.
  struct Side {
    WindowModel model;
    double plane = 0, quad = 0;  // measured variance over s.window's plane / quadratic
  };
  std::vector<Side> sides;
  const DepthStats::Scale* main = nullptr;
  for (const DepthStats::Scale& sc : s.scales)
    if (sc.window == s.window && sc.windows >= 20) main = &sc;
  auto shape_scale = [&](int window) -> const DepthStats::Scale* {
    if (shape == nullptr) return nullptr;
    for (const DepthStats::Scale& sc : shape->scales)
      if (sc.window == window && sc.windows >= 20) return &sc;
    return nullptr;
  };
  auto noise_of = [&](const DepthStats::Scale& sc) {
    const DepthStats::Scale* q = shape_scale(sc.window);
    return std::pair{q ? less_shape(sc.sigma, q->sigma) : sc.sigma,
                     q ? less_shape(sc.sigma_quad, q->sigma_quad) : sc.sigma_quad};
  };
  if (main != nullptr && main->sigma > 0 && main->sigma_quad > 0) {
    const auto [mp, mq] = noise_of(*main);
    for (const DepthStats::Scale& sc : s.scales) {
      if (&sc == main || sc.windows < 20 || sc.window < 5 || sc.sigma <= 0) continue;
      const auto [p, q] = noise_of(sc);
      sides.push_back({WindowModel(sc.window), p * p / (mp * mp), q * q / (mq * mq)});
    }
  }
  const WindowModel m(s.window);
  // Every window's sums of one field; a share's mix is their weighted sum.
  struct Sums {
    double u = 0, v = 0;
    FieldSums main;
    std::vector<FieldSums> sides;
  };
  // The pixel-scale field has ax.kernel's shape, the low one is Gaussian.
  auto sums_of = [&](double u, double v, AxialKernel k = AxialKernel::gaussian) {
    Sums x{u, v, m.sums(u, v, true, k), {}};
    for (const Side& sd : sides) x.sides.push_back(sd.model.sums(u, v, false, k));
    return x;
  };
  Sums mix;  // scratch, reused
  auto mixed = [&](const Sums& a, const Sums& b, double share) -> const Sums& {
    mix.main = FieldSums{};
    mix.main.add(a.main, 1 - share);
    mix.main.add(b.main, share);
    mix.sides.assign(sides.size(), FieldSums{});
    for (std::size_t k = 0; k < sides.size(); ++k) {
      mix.sides[k].add(a.sides[k], 1 - share);
      mix.sides[k].add(b.sides[k], share);
    }
    return mix;
  };
  auto cost = [&](const Sums& x) {
    const WindowResponse r = m.response(x.main);
    double c = 0;
    for (int l = 0; l < kCorrelationLags; ++l) {
      const double dr = r.correlation_rows[l] - s.correlation_rows[l];
      const double dc = r.correlation_cols[l] - s.correlation_cols[l];
      c += dr * dr + dc * dc;
    }
    const double dq = r.quad_variance_factor / r.variance_factor - ratio;
    c += dq * dq;
    for (std::size_t k = 0; k < sides.size(); ++k) {
      // Per pixel of each window: the traces over their degrees of freedom.
      const int N = sides[k].model.n * sides[k].model.n, M = s.window * s.window;
      const double p = (x.sides[k].plane / (N - 3)) / (x.main.plane / (M - 3));
      const double q = (x.sides[k].quad / (N - 6)) / (x.main.quad / (M - 6));
      const double ep = std::log(p / sides[k].plane), eq = std::log(q / sides[k].quad);
      c += ep * ep + eq * eq;
    }
    return c;
  };
  // Widths [px]: the pixel-scale field white or 0.4-4 px (a Matern's ranges 3-20 px, where
  // its filter follows the covariance: AxialNoise); the low one 1.5-20 px.
  const bool matern = ax.kernel == AxialKernel::matern52, with_low = !matern;
  const double w_lo = matern ? kMinMaternRangePx : 0.3, w_hi = matern ? 20.0 : 4.0;
  const std::vector<double> fine = matern ? std::vector<double>{kMinMaternRangePx, 3.5, 4.5, 6.0, 8.0, 10.5, 14.0, 20.0}
                                          : std::vector<double>{0.4, 0.6, 0.8, 1.0, 1.25, 1.5, 1.8, 2.2, 2.7, 3.3, 4.0};
  const std::vector<double> coarse = {1.5, 2.0, 2.7, 3.5, 4.5, 6.0, 8.0, 10.5, 14.0, 20.0};
  std::vector<Sums> pix, low;
  if (!matern) pix.push_back(sums_of(0, 0));
  for (const double u : fine)
    for (const double v : fine) pix.push_back(sums_of(u, v, ax.kernel));
  if (with_low)
    for (const double u : coarse)
      for (const double v : coarse) low.push_back(sums_of(u, v));
  constexpr int kShares = 20;  // 0, 0.05, ..., 0.95
  double best = std::numeric_limits<double>::infinity();
  Eigen::Matrix<double, 5, 1> x;  // pixel u, v; share; low u, v
  for (const Sums& a : pix) {
    if (const double c = cost(a); c < best) best = c, x << a.u, a.v, 0, coarse[0], coarse[0];
    for (const Sums& b : low)
      for (int k = 1; k < kShares; ++k) {
        const double sh = 0.05 * k;
        if (const double c = cost(mixed(a, b, sh)); c < best) best = c, x << a.u, a.v, sh, b.u, b.v;
      }
  }
  // Pattern search from the grid's best: a white pixel-scale field stays white, widths keep
  // to their ranges, and a share of 0 leaves the low field's widths alone.
  const bool white = x[0] == 0;
  auto eval = [&](const Eigen::Matrix<double, 5, 1>& y) {
    const Sums a = sums_of(y[0], y[1], ax.kernel);
    if (y[2] == 0) return cost(a);
    const Sums b = sums_of(y[3], y[4]);
    return cost(mixed(a, b, y[2]));
  };
  Eigen::Matrix<double, 5, 1> step;
  step << 0.1, 0.1, 0.025, 0.5, 0.5;
  Eigen::Matrix<double, 5, 1> lo, hi;
  lo << w_lo, w_lo, 0, 0.5, 0.5;
  hi << w_hi, w_hi, 0.95, 20, 20;
  for (int it = 0; it < 40 && step[2] > 1e-3; ++it) {
    bool moved = false;
    for (int d = 0; d < 5; ++d) {
      if ((white && d < 2) || (x[2] == 0 && d > 2) || (!with_low && d == 2)) continue;
      for (const double sign : {-1.0, 1.0}) {
        Eigen::Matrix<double, 5, 1> y = x;
        y[d] = std::clamp(y[d] + sign * step[d], lo[d], hi[d]);
        if (y[d] == x[d]) continue;
        if (const double c = eval(y); c < best) best = c, x = y, moved = true;
      }
    }
    if (!moved) step *= 0.5;
  }
  ax.correlation_px = x[0];
  ax.correlation_cols_px = white ? 0 : x[1];
  ax.low_share = x[2];
  if (x[2] > 0) ax.low_rows_px = x[3], ax.low_cols_px = x[4];
  const WindowResponse r = window_response(ax, s.window);
  std::string line(600, '\0');
  const int len = std::snprintf(
      line.data(), line.size(),
      "structure: pixel-scale field (%s) %.2f x %.2f px (rows x columns), low-frequency field "
      "%.2f x %.2f px with %.2f of the variance; the model reads rows %.2f %.2f %.2f %.2f, "
      "columns %.2f %.2f %.2f %.2f at lags 1-4 (measured rows %.2f %.2f %.2f %.2f, columns "
      "%.2f %.2f %.2f %.2f), a quadratic/plane variance ratio %.2f (measured %.2f); %zu other "
      "window sides",
      std::string(to_string(ax.kernel)).c_str(), ax.rows_px(), ax.cols_px(), ax.low_rows_px,
      ax.low_cols_px, ax.low_share,
      r.correlation_rows[0], r.correlation_rows[1], r.correlation_rows[2], r.correlation_rows[3],
      r.correlation_cols[0], r.correlation_cols[1], r.correlation_cols[2], r.correlation_cols[3],
      s.correlation_rows[0], s.correlation_rows[1], s.correlation_rows[2], s.correlation_rows[3],
      s.correlation_cols[0], s.correlation_cols[1], s.correlation_cols[2], s.correlation_cols[3],
      r.quad_variance_factor / r.variance_factor, ratio, sides.size());
  line.resize(static_cast<std::size_t>(std::max(len, 0)));
  notes.push_back(line);
  return r;
}

}  // namespace

std::string_view to_string(NoiseStructure structure) {
  switch (structure) {
    case NoiseStructure::one_field: return "one-field";
    case NoiseStructure::two_term: return "two-term";
    case NoiseStructure::matern52: return "matern52";
    case NoiseStructure::two_scale: return "two-scale";
  }
  return "?";
}

NoiseStructure parse_noise_structure(std::string_view name) {
  for (const NoiseStructure s : kNoiseStructures)
    if (name == to_string(s)) return s;
  throw std::invalid_argument("noise structure '" + std::string(name) +
                              "': expected one-field, two-term, matern52 or two-scale");
}

std::string_view to_string(FrameHalf half) {
  switch (half) {
    case FrameHalf::all: return "all";
    case FrameHalf::even: return "even";
    case FrameHalf::odd: return "odd";
    case FrameHalf::near: return "near";
    case FrameHalf::far: return "far";
  }
  return "?";
}

FrameHalf parse_frame_half(std::string_view name) {
  for (const FrameHalf h : kFrameHalves)
    if (name == to_string(h)) return h;
  throw std::invalid_argument("frame half '" + std::string(name) +
                              "': expected all, even, odd, near or far");
}

std::vector<std::size_t> frame_half(const std::vector<io::DepthImage>& frames,
                                    const io::Intrinsics& intrinsics, FrameHalf half) {
  std::vector<std::size_t> out;
  if (half == FrameHalf::all || half == FrameHalf::even || half == FrameHalf::odd) {
    for (std::size_t i = 0; i < frames.size(); ++i)
      if (half == FrameHalf::all || (i % 2 == 0) == (half == FrameHalf::even)) out.push_back(i);
    return out;
  }
  std::vector<std::pair<double, std::size_t>> by_depth;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    std::vector<double> z;
    for (const std::uint16_t d : frames[i].data)
      if (d != 0) z.push_back(d * intrinsics.depth_scale);
    if (z.empty())
      throw std::invalid_argument("frame " + std::to_string(i) +
                                  " has no valid pixel: no median depth for a near/far half");
    by_depth.emplace_back(median_in_place(z), i);
  }
  std::sort(by_depth.begin(), by_depth.end());
  const std::size_t near = (by_depth.size() + 1) / 2;
  for (std::size_t j = half == FrameHalf::near ? 0 : near;
       j < (half == FrameHalf::near ? near : by_depth.size()); ++j)
    out.push_back(by_depth[j].second);
  std::sort(out.begin(), out.end());
  return out;
}

NoiseFit fit_noise(const DepthStats& s, const NoiseParams& start, const DepthStats* shape,
                   NoiseStructure structure) {
  if (structure == NoiseStructure::two_scale)
    throw std::invalid_argument("fit_noise: the two-scale structure is fitted by re-rendering "
                                "the frames (fit_noise_rerendered)");
  const int window = s.window;
  NoiseFit fit;
  fit.params = start;
  AxialNoise& ax = fit.params.axial;
  // The one-field model: the correlation width by bisection on the lag-1 reading (it grows
  // with the width), checked against lag 2 in the notes.
  ax.correlation_px = 0;
  ax.correlation_cols_px = 0;
  ax.low_share = 0;
  ax.pixel_depth_power = 0;  // nor a depth power of its own (a start such as sr300's has one)
  ax.kernel = AxialKernel::gaussian;  // the one-field and two-term models' fields
  double variance_factor = window_response(0, window).variance_factor;
  const double rho1 = s.correlation[0];
  if (structure == NoiseStructure::two_term) {
    variance_factor = fit_structure(s, shape, ax, fit.notes).variance_factor;
  } else if (structure == NoiseStructure::matern52) {
    ax.kernel = AxialKernel::matern52;
    variance_factor = fit_structure(s, shape, ax, fit.notes).variance_factor;
  } else if (rho1 > window_response(0.3, window).correlation[0]) {
    // Above about 4 px the reading saturates (near 0.9): a width there is not determined.
    double lo = 0.3, hi = 4.0;
    if (rho1 >= window_response(hi, window).correlation[0]) {
      lo = hi;
      fit.notes.emplace_back(
          "correlation width at the search limit (4 px): the lag-1 correlation is as high "
          "as a Gaussian kernel can explain in these windows, or higher (curvier "
          "surfaces?); sigma is not corrected for it");
    } else {
      for (int it = 0; it < 24; ++it) {  // to 4e-7 px
        const double mid = 0.5 * (lo + hi);
        (window_response(mid, window).correlation[0] < rho1 ? lo : hi) = mid;
      }
    }
    ax.correlation_px = 0.5 * (lo + hi);
    const WindowResponse wr = window_response(ax.correlation_px, window);
    if (lo < hi) variance_factor = wr.variance_factor;
    char line[256];
    std::snprintf(line, sizeof line,
                  "correlation width %.2f px from the lag-1 correlation %.2f; the model then "
                  "reads %.2f / %.2f at lags 2 / 3 (measured %.2f / %.2f)",
                  ax.correlation_px, rho1, wr.correlation[1], wr.correlation[2],
                  s.correlation[1], s.correlation[2]);
    fit.notes.emplace_back(line);
  }
  // The plane fit reads sigma * sqrt(variance_factor): undo it.
  const double unbias = 1.0 / std::sqrt(variance_factor);
  // Eq. of AxialNoise: sigma = a + c z^2 + k_theta g(z, theta), g = (theta / (pi/2 -
  // theta))^angle_power / sqrt(z), the start's power. Fitted jointly to the depth bins (windows
  // under depth_bin_max_angle) and the angle bins with 10 windows or more, each bin's model being
  // the median of the model over its own windows: even under 30 degrees the angle term is not
  // negligible on real frames, and the depth bins hold different mixes of angles (a torso face-on,
  // an arm oblique), which a fit of depth alone reads as a sigma that is not monotone in depth.
  // The model is AxialNoise::sigma itself, on points prepared once.
  struct Bin {
    std::vector<AxialNoise::Point> points;
    double y = 0;  // measured median sigma, unbiased [m]
  };
  std::vector<Bin> cells;
  int corrected = 0, uncorrected = 0;
  for (const bool by_depth : {true, false}) {
    const std::vector<SigmaBin>& bins = by_depth ? s.sigma_by_depth : s.sigma_by_angle;
    for (std::size_t k = 0; k < bins.size(); ++k) {
      const SigmaBin& b = bins[k];
      if (b.windows < kMinBinWindows) continue;
      Bin bin;
      for (const DepthStats::Window& w : s.samples) {
        if (!in_sigma_bin(w, b, by_depth, s.depth_bin_max_angle)) continue;
        bin.points.push_back(ax.point(w.z, w.angle));
      }
      double m = b.sigma;  // the median of these windows' sigma
      if (shape != nullptr) {
        const std::vector<SigmaBin>& q = by_depth ? shape->sigma_by_depth : shape->sigma_by_angle;
        if (k < q.size() && q[k].windows >= kMinBinWindows && std::abs(q[k].lo - b.lo) < 1e-9) {
          // Noise and shape add in quadrature; a bin the shape explains keeps a tenth.
          m = std::sqrt(std::max(m * m - q[k].sigma * q[k].sigma, 0.01 * m * m));
          ++corrected;
        } else {
          ++uncorrected;
        }
      }
      bin.y = m * unbias;
      cells.push_back(std::move(bin));
    }
  }
  if (shape != nullptr) {
    fit.notes.push_back("sigma corrected for the surfaces' own shape in " + std::to_string(corrected) +
                        " bins (" + std::to_string(uncorrected) +
                        " without 10 windows of the re-rendered surfaces)");
  }
  // Minimax in relative error, non-negative: the largest |model / measured - 1| over the
  // bins is what a comparison of a simulation with the camera (linksight fidelity) sees,
  // so that is what the fit keeps small. A coarse grid, then a pattern search around its
  // best point.
  // The largest relative error at x; stops once it reaches `enough` (the best so far),
  // since the caller then discards it.
  std::vector<double> model;
  auto worst = [&](const Eigen::Vector3d& x, double enough) {
    double e = 0;
    for (const Bin& b : cells) {
      AxialNoise m = ax;
      m.a = x[0];
      m.c = x[1];
      m.k_theta = x[2];
      model.resize(b.points.size());
      for (std::size_t i = 0; i < model.size(); ++i) model[i] = m.sigma(b.points[i]);
      e = std::max(e, std::abs(median_in_place(model) / b.y - 1));
      if (e >= enough) break;
    }
    return e;
  };
  double best = std::numeric_limits<double>::infinity();
  Eigen::Vector3d coef = Eigen::Vector3d::Zero();
  if (cells.size() >= 3) {
    const Eigen::Vector3d span(1e-3, 3e-3, 1.5e-3);  // a [m], c [1/m], k_theta [m^1.5]
    constexpr int kSteps = 20;
    for (int i = 0; i <= kSteps; ++i)
      for (int j = 0; j <= kSteps; ++j)
        for (int k = 0; k <= kSteps; ++k) {
          const Eigen::Vector3d x(span[0] * i / kSteps, span[1] * j / kSteps, span[2] * k / kSteps);
          const double e = worst(x, best);
          if (e < best) best = e, coef = x;
        }
    Eigen::Vector3d step = span / kSteps;
    for (int it = 0; it < 60; ++it) {
      bool moved = false;
      for (int d = 0; d < 3; ++d)
        for (const double sign : {-1.0, 1.0}) {
          Eigen::Vector3d x = coef;
          x[d] = std::max(0.0, x[d] + sign * step[d]);
          const double e = worst(x, best);
          if (e < best) best = e, coef = x, moved = true;
        }
      if (!moved) step *= 0.5;
    }
  }
  if (cells.size() >= 3) {
    ax.a = coef[0];
    ax.c = coef[1];
    ax.k_theta = coef[2];
  } else {
    fit.notes.push_back("axial a_m, c_per_m, k_theta kept: under 3 depth or angle bins "
                        "with 10 flat windows");
  }
  if (s.projector_side != 0) {
    fit.params.shadow.baseline = s.baseline;
  } else {
    fit.notes.push_back("shadow.baseline_m kept (" + std::to_string(start.shadow.baseline) +
                        "): the shadows decide no side (too few edges, or widths that do "
                        "not follow the depth gap)");
  }
  if (!s.hole_sizes.empty() && s.valid_px > 0) {
    // Holes fall anywhere; they show only on a valid surface, and only away from its edges.
    Dropouts& d = fit.params.dropouts;
    d.hole_rate = std::min(1e4, s.holes_per_frame * static_cast<double>(s.pixels) /
                                    static_cast<double>(s.valid_px));
    d.hole_median_px =
        std::clamp(quantile(s.hole_sizes, 0.5), 1.0, static_cast<double>(Dropouts::kMaxHolePx));
    d.hole_p90_px = std::clamp(quantile(s.hole_sizes, 0.9), d.hole_median_px,
                               static_cast<double>(Dropouts::kMaxHolePx));
  } else {
    fit.notes.emplace_back("dropouts.hole_rate, hole_median_px, hole_p90_px kept: no interior hole");
  }
  char line[256];
  // The edge band, on the side away from the shadow (the shadow's own band is geometry).
  // Its first pixel past the near surface is invalid if the near edge pixel was dropped
  // (p_drop) or else the far one (band_p1); its second if, respectively, the far one was
  // (band_p1) or the one after (band_p2).
  const EdgeSide& other = s.projector_side < 0 ? s.near_right : s.near_left;
  EdgeEffects& e = fit.params.edges;
  if (s.projector_side != 0 && other.edges >= 20 && e.p_drop < 1) {
    const double q = e.p_drop;
    e.band_p1 = std::clamp((other.invalid_1px - q) / (1 - q), 0.0, 1.0);
    e.band_p2 = std::clamp((other.invalid_2px - q * e.band_p1) / (1 - q), 0.0, 1.0);
    std::snprintf(line, sizeof line,
                  "edges.band_p1/band_p2 from the non-shadow side's %.2f / %.2f invalid at "
                  "1 / 2 px, given edges.p_drop %.2f (kept: not separable from them)",
                  other.invalid_1px, other.invalid_2px, q);
    fit.notes.emplace_back(line);
  } else {
    fit.notes.emplace_back("edges.band_p1, band_p2, p_drop kept: no side decided, or under 20 "
                           "edges on the side away from the shadow");
  }
  if (s.flying > 0 && e.p_drop < 1) {
    // The model moves a near-side edge pixel that was not dropped (1 - p_drop) with
    // p_flying, to a position uniform in flying_position +- flying_spread; the statistic
    // counts it when it lands 10-90% of the way across. An interquartile range of a
    // uniform is its half-width.
    e.flying_position = s.flying_position;
    e.flying_spread = std::clamp(s.flying_iqr, 0.0, 0.5);
    const double lo = std::max(0.0, e.flying_position - e.flying_spread);
    const double hi = std::min(1.0, e.flying_position + e.flying_spread);
    const double seen =
        hi > lo ? std::max(0.0, std::min(hi, 0.9) - std::max(lo, 0.1)) / (hi - lo) : 1.0;
    e.p_flying = std::clamp(s.flying_per_edge / ((1 - e.p_drop) * std::max(seen, 0.05)), 0.0, 1.0);
    std::snprintf(line, sizeof line,
                  "lone flying pixels at %.3f of the discontinuities (flying pixels %.1f%% of "
                  "band neighbours) at %.2f +- %.2f of the gap: edges.p_flying given p_drop "
                  "%.2f",
                  s.flying_per_edge, 100 * s.flying_rate, s.flying_position, s.flying_iqr,
                  e.p_drop);
  } else {
    std::snprintf(line, sizeof line, "edges.p_flying, flying_position, flying_spread kept: %s",
                  s.flying > 0 ? "p_drop is 1" : "no flying pixel");
  }
  fit.notes.emplace_back(line);
  // The camera's rule for steps: on where the recording reports under one pair of valid
  // 4-neighbours more than the jump apart per million, over enough pairs to tell (the SR305
  // frames: none in 1.27 million).
  // The statistic counts steps over its neighbour_jump, the rule drops them over edges.jump:
  // only where the two are the same does the one say what the other does.
  constexpr long kMinStepPairs = 100000;
  if (!e.enabled || e.jump != s.neighbour_jump) {
    fit.notes.emplace_back("edges.drop_steps kept: the edge model is off, or its jump_m is not "
                           "the statistics' neighbour_jump");
  } else if (s.neighbour_pairs >= kMinStepPairs) {
    e.drop_steps = s.neighbour_jumps * 1000000 < s.neighbour_pairs;
    std::snprintf(line, sizeof line,
                  "edges.drop_steps %s: %ld of %ld valid neighbour pairs step more than the "
                  "statistics' neighbour_jump",
                  e.drop_steps ? "on" : "off", s.neighbour_jumps, s.neighbour_pairs);
    fit.notes.emplace_back(line);
  } else {
    fit.notes.emplace_back("edges.drop_steps kept: under 100000 valid neighbour pairs");
  }
  fit.notes.emplace_back("lateral.sigma_px and dropouts.max_incidence, min_signal kept: not "
                         "measured");
  return fit;
}

}  // namespace linksight::sim
