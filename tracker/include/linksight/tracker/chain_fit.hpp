#pragma once
/// @file Centres from a model fit, not from a mean (issue 17, part 2): the chain state
/// (chain_state.hpp) fitted to the points by robust Gauss–Newton on the distance from each
/// point to the component surfaces (ball of known radius ∪ neck capsule, the same shape as
/// the SDF metric, ComponentGeometry::sdf).

#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

#include "linksight/tracker/chain_state.hpp"
#include "linksight/tracker/cloud.hpp"
#include "linksight/tracker/fields.hpp"
#include "linksight/tracker/geometry.hpp"
#include "linksight/tracker/init.hpp"

namespace linksight {

class ChainPassDevice;  // a back end's own passes (Backend::chain_pass_device)

struct ChainFitParams {
  int max_iterations = 20;  ///< Levenberg-Marquardt steps tried per stage (coarse, full)
  /// Huber loss: residuals beyond this weigh linearly, not quadratically (flying pixels,
  /// rim pixels, stray points) [m].
  double huber = 0.001;
  /// A point farther than this from every component surface is not the link's [m].
  double max_distance = 0.01;
  /// Stop after a step that moves no centre more than this [m] (0.03 mm: the step is
  /// taken, and what it leaves is about an eighth of it, well below the noise-free target
  /// of 0.05 mm; each further step is a pass over the points).
  double tolerance = 3e-5;
  /// A step that leaves every centre within this of where the points were last searched
  /// for their nearest component reuses that search (a pass then costs one component's
  /// distance per point); 0: search on every pass [m].
  double reassociate = 0.002;
  /// Coarse to fine: a fit first converges on every coarse_stride-th point of each block
  /// (its sums scaled by the stride, so priors and thresholds weigh as on all points),
  /// then takes one pass over every point, whose step is taken unchecked when it moves no
  /// centre more than coarse_accept (the coarse fit is that near the full one: one
  /// Gauss-Newton step from there lands within the tolerance); a larger step goes on as a
  /// full fit. Most frames then cost one pass over every point instead of 2-3. 1: off, every
  /// pass over every point. Used only where the first coarse pass finds every component
  /// at least kCoarseMinPerComponent coarse inliers: a chain with a hidden or barely seen
  /// component is fitted on every point from the start.
  int coarse_stride = 8;
  double coarse_accept = 0.0005;  ///< [m]
  /// With a shape prior: how far a joint's bend may change from the prior's, as one σ
  /// (the link holds its shape unless pushed; a hidden joint keeps its bend) [rad].
  double bend_sigma = 0.3 * 3.14159265358979323846 / 180.0;
  /// After an initialization (no shape yet): how far a joint may bend from straight, as
  /// one σ; a joint the points do not show comes out straight [rad].
  double straight_sigma = 5.0 * 3.14159265358979323846 / 180.0;
  /// Loss: a frame whose fit keeps fewer than this fraction of the previous frame's
  /// inliers, or whose inliers' RMS distance exceeds misfit_rms, is fitted again from a
  /// fresh initialization, and that fit is taken when its robust cost is below
  /// reinit_gain times the tracked fit's (an occlusion also drops inliers: a fresh start
  /// from the visible part must be far better, not merely as good, to replace the track).
  double misfit_inliers = 0.5;
  double misfit_rms = 0.002;  ///< [m]
  double reinit_gain = 0.5;
  /// Free space (with a depth image): a component with fewer inliers than
  /// free_space_below whose place a pixel's ray passes through to a surface more than
  /// free_space_margin behind it (the camera sees through where it would be) is pushed out
  /// of that ray, each such ray weighing as one point.
  int free_space_below = 10;
  double free_space_margin = 0.005;  ///< [m]
  /// With a base pose: a component with fewer inliers than this is held where it was last
  /// seen in the base frame (ChainAnchor::held), not where the seen part's bends put it.
  int hidden_below = 10;
  /// The largest bend between neighbouring components [rad]: the chain's cone limit, not
  /// a key of this block (a scene sets it from chain.cone_limit_deg).
  double cone_limit = 25.0 * 3.14159265358979323846 / 180.0;

  template <class Archive>
  void fields(Archive& ar) {
    ar("max_iterations", max_iterations, fields::in(1, 1000));
    ar("huber_m", huber, fields::in(1e-6, 0.1));
    ar("max_distance_m", max_distance, fields::in(1e-4, 1));
    ar("tolerance_m", tolerance, fields::in(0, 1e-3));
    ar("reassociate_m", reassociate, fields::in(0, 0.01));
    ar("coarse_stride", coarse_stride, fields::in(1, 64));
    ar("coarse_accept_m", coarse_accept, fields::in(0, 0.002));
    ar("bend_sigma_deg", bend_sigma, fields::deg(fields::in(0.01, 90)));
    ar("straight_sigma_deg", straight_sigma, fields::deg(fields::in(0.01, 90)));
    ar("misfit_inliers", misfit_inliers, fields::in(0, 1));
    ar("misfit_rms_m", misfit_rms, fields::in(1e-4, 1));
    ar("reinit_gain", reinit_gain, fields::in(0, 1));
    ar("free_space_below", free_space_below, fields::in(0, 1000000));
    ar("free_space_margin_m", free_space_margin, fields::in(0, 1));
    ar("hidden_below", hidden_below, fields::in(0, 1000000));
  }
  /// Throws fields::FieldError naming the key (cone_limit as the chain's cone_limit_deg).
  void validate() const;
};

/// Where a known base pose puts the chain's first component (issue 17, part 4): ball 0's
/// centre near `c0` and component 0's axis near `axis0`, each with its own σ. Weighed
/// like the shape prior: a deviation of one σ costs what a point at the Huber threshold
/// does, so points that show the first component outweigh it, and where they do not (the
/// base end hidden) it holds the chain's index and place.
struct ChainAnchor {
  Eigen::Vector3d c0 = Eigen::Vector3d::Zero();     ///< [m, C]
  double sigma_m = 0.001;                           ///< of c0 [m]
  Eigen::Vector3d axis0 = Eigen::Vector3d::UnitZ(); ///< unit [C]
  double sigma_rad = 0.01;                          ///< of axis0 [rad]
  /// Where each ball was when last seen, moved with the base ([m, C]; empty: none known):
  /// a ball with fewer inliers than ChainFitParams::hidden_below is held there, σ
  /// held_sigma_m, so that a hidden part stays where the base carries it rather than
  /// turning with each frame's noisy bends of the seen part next to it.
  std::vector<std::optional<Eigen::Vector3d>> held;
  double held_sigma_m = 0.001;  ///< [m]
};

/// ChainFitParams::coarse_stride: the coarse stage runs only on a cloud of at least this
/// many coarse points per component, and goes on only where each component has this many
/// coarse inliers (fewer would steer the full fit, not start it).
inline constexpr std::size_t kCoarseMinPerComponent = 20;

struct ChainFitResult {
  int iterations = 0;       ///< accepted Levenberg-Marquardt steps
  /// Passes over the points: one per step tried, plus each stage's first (a coarse stage
  /// cut short by a barely seen component counts its one pass).
  int passes = 0;
  int coarse_passes = 0;    ///< of them, coarse ones (over every coarse_stride-th point)
  int searches = 0;         ///< of them, passes that searched their points' components
  /// Points within max_distance of the fitted chain's surface, and their RMS distance to
  /// it [m], from the last accepted pass: its association may be one reused from up to
  /// reassociate away (so at most the true count and at least the true RMS), and the
  /// final step taken unchecked (within the tolerance, or within coarse_accept after the
  /// coarse stage) is not in them.
  std::size_t inliers = 0;
  double rms = 0.0;
  double cost = 0.0;  ///< robust cost of the points, free-space rays and held balls (no priors)
  double anchor_cost = 0.0; ///< the anchor's cost (0 without one), in the cost's units
  int free_space_rays = 0;  ///< rays through a few-point component's place, at the end
  std::vector<std::int64_t> counts;  ///< inliers nearest each component (count entries)
};

/// The component a point lies nearest to (by the component SDF) and its signed distance
/// to that component's surface [m]; the component is -1 when the chain has none.
struct SurfaceHit {
  int component = -1;
  double distance = 0.0;
};
[[nodiscard]] SurfaceHit nearest_surface(const Eigen::Vector3d& p, const ChainState& chain,
                                         const ComponentGeometry& geometry);

/// Fits `chain` (the start, updated in place) to `points` [m, C]: each pass associates
/// every point with its nearest component surface and sums, per component, the
/// Huber-weighted normal equations in that component's centre and axis; one damped
/// Gauss–Newton (Levenberg–Marquardt) step in ball 0's centre and the axes' tangent
/// rotations follows, the axes renormalized and the joints bent back within the cone
/// limit. The pitch holds exactly throughout. A step that raises the cost is dropped.
/// `threads` (0: one per core) share the passes; points are summed in fixed blocks in a
/// fixed order, so the result is the same bits for any thread count. `shape`, when
/// given, is a shape prior: each joint's bend is held near `shape`'s with σ
/// params.bend_sigma (the previous frame's shape, moved with the link). `anchor`, when
/// given, holds the first component where a known base puts it. `device`, when given,
/// runs the passes over the points instead of `threads` (it holds the same points: its
/// set_chain_points was called with them) and gives the same bits. `depth`, when given,
/// adds the free-space evidence (ChainFitParams::free_space_below).
ChainFitResult fit_chain(const PointsView& points, ChainState& chain,
                         const ComponentGeometry& geometry, const ChainFitParams& params,
                         int threads = 1, const ChainState* shape = nullptr,
                         const ChainAnchor* anchor = nullptr, ChainPassDevice* device = nullptr,
                         const DepthView* depth = nullptr);

/// The anchor's cost at `chain`, in the fit's cost units (ChainFitResult::anchor_cost): to
/// compare fits made under different anchors under one.
[[nodiscard]] double anchor_cost(const ChainState& chain, const ChainAnchor& anchor,
                                 const ComponentGeometry& geometry, const ChainFitParams& params);

/// The fit's robust cost (Huber, points beyond max_distance counted at it) of `chain` over
/// every `stride`-th point: to choose between starts cheaply.
[[nodiscard]] double chain_cost(const PointsView& points, const ChainState& chain,
                                const ComponentGeometry& geometry, const ChainFitParams& params,
                                int threads = 1, std::size_t stride = 1);

/// slide_to_best's candidate shifts: one pass over the points each.
inline constexpr int kSlideCandidates = 8;

/// `start` slid along itself by the shift in [-pitch/2, pitch/2) (steps of pitch/8) whose
/// points fit best (robust cost, one pass each). A start laid out from the cloud's extent
/// (LSQ) is a ball radius or more off along the link, and a fit from about half a pitch
/// off settles with the balls on the necks: this puts the start within the fit's reach.
[[nodiscard]] ChainState slide_to_best(const PointsView& points, const ChainState& start,
                                       const ComponentGeometry& geometry,
                                       const ChainFitParams& params, int threads = 1);

}  // namespace linksight
