#pragma once
/// @file The shape tracker: Algorithm 1's frame loop (association by a back end, then a
/// mode's policies: init, update, re-initialization trigger, output; mode.hpp).

#include <Eigen/Geometry>

#include <chrono>
#include <cstdint>
#include <memory>
#include <span>
#include <string_view>
#include <vector>

#include "linksight/tracker/backend.hpp"
#include "linksight/tracker/limits.hpp"
#include "linksight/tracker/cloud.hpp"
#include "linksight/tracker/geometry.hpp"
#include "linksight/tracker/init.hpp"
#include "linksight/tracker/mode.hpp"
#include "linksight/tracker/model.hpp"

namespace linksight {

// kMaxNodes, kMaxIterations, kMaxThreads: limits.hpp.

/// A known base pose (issue 17, part 4): on the robot, the flange pose from the arm's
/// joints through the hand–eye calibration. The base frame B is the chain's: ball 0's
/// centre at its origin, component 0 leaving along its +X when joint 0 is straight.
/// Step() takes the pose X_CB per frame; these are its σ, and whether `linksight
/// run`/`sweep` give one (the true pose with an error drawn once per episode).
struct BasePriorParams {
  bool enabled = false;    ///< run/sweep pass the true base pose, with error, to step()
  double sigma_m = 0.001;  ///< the base position's σ, per axis [m]
  double sigma_rad = 0.5 * 3.14159265358979323846 / 180.0;  ///< its orientation's σ [rad]
  template <class Archive>
  void fields(Archive& ar) {
    ar("enabled", enabled);
    ar("sigma_m", sigma_m, fields::in(1e-6, 1));
    ar("sigma_deg", sigma_rad, fields::deg(fields::in(0.001, 90)));
  }
  void validate() const;  ///< throws fields::FieldError naming the key
};

struct TrackerParams {
  TrackerMode mode;         ///< a row of the mode table (default: paper)
  PolicyParams policy;      ///< each policy's own settings; the mode reads its policies'
  BackendKind backend = BackendKind::serial;
  OpenCLOptions opencl;     ///< used by BackendKind::opencl
  int threads = 0;          ///< parallel back ends: 0 = one per core
  BasePriorParams base_prior;  ///< chain-fit: how far a base pose given to step() is trusted
  int nodes = 12;           ///< M+1 reference vectors (M = 11 components)
  int iterations = 4;       ///< association/mean iterations per frame (Algorithm 1)
  double tolerance = 0.0;   ///< stop early when no node moves more than this [m]; 0: never
  bool compute_sdf = true;  ///< fill FrameResult::sdf_error (not counted in time_s)
  ComponentGeometry geometry;

  /// The keys of a scene's `tracker` block (fields.hpp). nodes, geometry, the LSQ pitch
  /// and the SOM seed come from the scene's chain and seed; opencl and compute_sdf from
  /// the command line.
  template <class Archive>
  void fields(Archive& ar) {
    ar("mode", mode, parse_mode);
    policy.lsq_init.fields(ar);  // init, poly_order, max_points
    policy.som_init.fields(ar);  // som_init
    ar("backend", backend, parse_backend);
    ar("threads", threads, fields::in(0, kMaxThreads));
    ar("iterations", iterations, fields::in(1, kMaxIterations));
    ar("tolerance_m", tolerance, fields::in(0, 1));
    ar("chain_fit", policy.chain_fit);  // update chain-fit's settings, a block
    ar("base_prior", base_prior);
  }
  /// Throws fields::FieldError naming the offending key and value.
  void validate() const;
};

enum class InitReason : std::uint8_t {
  none,                 ///< continued from the previous frame's output
  first_frame,          ///< no previous output (first frame or after reset())
  empty_neighbourhood,  ///< a node had no points (Sec. IV.C): re-initialized by LSQ
  /// chain-fit: the fit lost the points (inliers fell, or residuals rose; ChainFitParams)
  /// and a fit from a fresh initialization explains them far better
  misfit,
};

enum class LostReason : std::uint8_t {
  none,
  empty_cloud,      ///< the cloud has no points at all
  all_non_finite,   ///< every point had a NaN or Inf coordinate
  too_few_points,   ///< fewer finite points than nodes
  too_many_points,  ///< more than kMaxPoints usable points
};

[[nodiscard]] std::string_view to_string(InitReason reason);
[[nodiscard]] std::string_view to_string(LostReason reason);

/// Output of one frame.
struct FrameResult {
  Nodes nodes;                       ///< M+1 reference vectors, camera frame [m], as the mode's output policy gives them
  std::vector<std::int64_t> counts;  ///< |N_j| of the last iteration
  int iterations = 0;                ///< iterations run (chain-fit: passes over the points)
  bool reinit = false;               ///< LSQ re-initialization fired (Sec. IV.C)
  InitReason init_reason = InitReason::none;
  int reinit_node = -1;  ///< first node found with an empty neighbourhood
  bool lost = false;
  LostReason lost_reason = LostReason::none;
  std::size_t n_points = 0;        ///< finite points used
  std::size_t n_non_finite = 0;    ///< points dropped for NaN/Inf
  std::size_t n_out_of_range = 0;  ///< points dropped beyond kMaxCoordinate (100 m)
  double time_s = 0.0;             ///< tracking time (excludes the SDF metric) [s]
  double device_time_s = 0.0;      ///< kernel time on the device, within time_s (OpenCL) [s]
  double sdf_error = 0.0;          ///< mean |SDF| [m] (Eq. 16) of `nodes`; NaN when lost or disabled
};

/// Tracks one link over a sequence of clouds; each frame starts from the previous
/// frame's output. Holds its buffers, so a steady frame size allocates nothing.
class Tracker {
 public:
  explicit Tracker(const TrackerParams& params);  ///< validates params (throws)
  /// Runs `mode` instead of params.mode: a composition not in the mode table (to try one
  /// out before it gets a row).
  Tracker(const TrackerParams& params, const ModeSpec& mode);
  ~Tracker();
  Tracker(Tracker&&) noexcept;
  Tracker& operator=(Tracker&&) noexcept;

  /// Runs Algorithm 1 on one cloud with the mode's policies. Never throws for bad data: it
  /// reports `lost`. `X_CB`: the base's pose in the camera frame this frame, when known
  /// (BasePriorParams); `depth`: the frame's depth image, when known (free-space evidence,
  /// ChainFitParams::free_space_below). A mode whose update does not fit the chain ignores
  /// both. Throws std::invalid_argument for a pose that is not finite or not rigid, or a
  /// depth image whose size or intrinsics do not hold together.
  FrameResult step(const Cloud& cloud, const Eigen::Isometry3d* X_CB = nullptr,
                   const DepthView* depth = nullptr);
  /// Forgets the previous output; the next frame initializes from scratch.
  void reset();

  [[nodiscard]] const TrackerParams& params() const { return params_; }
  /// Associations of the finite points of the last step's final iteration.
  [[nodiscard]] std::span<const std::int32_t> last_association() const;

 private:
  struct State;
  // The frame's output from the state's nodes, its time and its SDF error.
  FrameResult& finish(FrameResult& r, std::chrono::steady_clock::time_point t0);
  TrackerParams params_;
  std::unique_ptr<State> state_;
};

}  // namespace linksight
