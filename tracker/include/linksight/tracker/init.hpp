#pragma once
/// @file Initialization of the reference vectors (Section IV.A, Eqs. 9–10) and the
/// accelerated-SOM baseline's initializations (Croom 2010 / Baader 1994).

#include <cstdint>
#include <optional>
#include <span>
#include <vector>
#include <string_view>

#include "linksight/tracker/fields.hpp"
#include "linksight/tracker/model.hpp"

namespace linksight {

/// Structure-of-arrays view of finite points in the camera frame [m].
struct PointsView {
  std::span<const float> x, y, z;
  [[nodiscard]] std::size_t size() const { return x.size(); }
};

enum class InitMethod {
  paper,  ///< Eq. 9 as printed: y = a(x), y = b(z), sampled over the marginal ranges
  pca,    ///< polynomial in the principal-axis frame, sampled at the component pitch
};

/// "paper" / "pca"; parse throws std::invalid_argument naming the value and the choices.
[[nodiscard]] std::string_view to_string(InitMethod method);
[[nodiscard]] InitMethod parse_init(std::string_view name);

struct InitParams {
  InitMethod method = InitMethod::pca;
  int poly_order = 3;             ///< polynomial order m of Eq. 9
  std::size_t max_points = 4000;  ///< thin the cloud to at most this many points (0: all)
  double pitch = 0.045;           ///< node spacing along the curve for `pca` [m]
  /// The keys in a scene's `tracker` block (pitch is the chain's, not a key).
  template <class Archive>
  void fields(Archive& ar) {
    ar("init", method, parse_init);
    ar("poly_order", poly_order, fields::in(1, 9));
    ar("max_points", max_points, fields::in(0, 1e7));
  }
  void validate() const;  ///< throws fields::FieldError naming the key
};

/// LSQ initialization: `n_nodes` ordered reference vectors. When `previous` is given
/// the result is oriented so that node 0 is at the end nearer previous node 0 (keeps
/// the topological order across re-initialization); otherwise node 0 is the end with the
/// smaller coordinate along the camera axis in which the link extends most (left end of
/// a horizontal link, top end of a hanging one). Requires points.size() >= 1.
[[nodiscard]] Nodes lsq_init(const PointsView& points, int n_nodes, const InitParams& params,
                             const Nodes* previous = nullptr);

/// The indices (ascending) of the points in the largest connected cluster: two points
/// are linked when their cells of a `cell`-sized grid touch (26-neighbourhood), so points
/// closer than `cell` always are and points farther than 2√3 `cell` never directly are;
/// a cluster is what links connect. For an initialization that should see the link and
/// not clutter set apart from it (a mug behind, a table edge). Ties go to the cluster
/// holding the lowest point index. Throws std::invalid_argument when cell < 1e-4 m or a
/// point is not finite or is 2^20 cells or more from the origin.
[[nodiscard]] std::vector<std::size_t> largest_cluster(const PointsView& points, double cell);

enum class SomInit {
  straight_line,  ///< evenly spaced on the principal-axis segment spanned by the cloud
  random_sample,  ///< nodes drawn from the cloud with a seeded generator, unordered
};

/// "straight-line" / "random-sample"; parse throws std::invalid_argument naming the value.
[[nodiscard]] std::string_view to_string(SomInit method);
[[nodiscard]] SomInit parse_som_init(std::string_view name);

/// The accelerated-SOM baseline's initialization. `seed` feeds random_sample only.
[[nodiscard]] Nodes som_init(const PointsView& points, int n_nodes, SomInit method,
                             std::uint64_t seed);

/// Least-squares polynomial coefficients c_0..c_m of v ≈ Σ c_k u^k (Eq. 10), solved
/// in a centred, scaled abscissa for conditioning; returns coefficients in u.
/// Order is reduced to n-1 when there are fewer points than coefficients.
struct Polynomial {
  Eigen::VectorXd coeffs;  ///< in the normalized abscissa t = (u - u0) / s
  double u0 = 0.0, scale = 1.0;
  [[nodiscard]] double operator()(double u) const;
};
[[nodiscard]] Polynomial fit_polynomial(std::span<const double> u, std::span<const double> v,
                                        int order);

}  // namespace linksight
