#pragma once
/// @file The shape tracker: SOM with LSQ initialization and re-initialization
/// (Section IV, Algorithm 1), or the accelerated-SOM baseline.

#include <cstdint>
#include <memory>
#include <span>
#include <string_view>
#include <vector>

#include "linksight/tracker/backend.hpp"
#include "linksight/tracker/cloud.hpp"
#include "linksight/tracker/geometry.hpp"
#include "linksight/tracker/init.hpp"
#include "linksight/tracker/model.hpp"

namespace linksight {

enum class TrackerMode {
  paper,            ///< LSQ init, re-initialization on an empty neighbourhood (Sec. IV)
  accelerated_som,  ///< baseline: straight-line/random init, no LSQ re-initialization
  /// paper's SOM, then each output node moved from the seen surface to the ball centre:
  /// 2/3 r further along its viewing ray (not in the paper; see kCentreOffset)
  paper_centred,
};

/// A SOM node is the mean of the surface points nearest it: on a ball seen from afar,
/// the mean of its visible cap, which (sampled evenly over the image disc) lies
/// 2/3 r in front of the centre along the viewing ray. paper_centred adds this back.
inline constexpr double kCentreOffset = 2.0 / 3.0;  ///< of the ball radius

/// Upper bounds that validate() enforces: beyond them a value is a typo, not a setting.
inline constexpr int kMaxNodes = 1000;
inline constexpr int kMaxIterations = 1000;
inline constexpr int kMaxThreads = 1024;

struct TrackerParams {
  TrackerMode mode = TrackerMode::paper;
  InitParams init;                            ///< LSQ init (paper mode)
  SomInit som_init = SomInit::straight_line;  ///< init of the accelerated-SOM mode
  BackendKind backend = BackendKind::serial;
  OpenCLOptions opencl;     ///< used by BackendKind::opencl
  int threads = 0;          ///< parallel back ends: 0 = one per core
  int nodes = 12;           ///< M+1 reference vectors (M = 11 components)
  int iterations = 4;       ///< association/mean iterations per frame (Algorithm 1)
  double tolerance = 0.0;   ///< stop early when no node moves more than this [m]; 0: never
  std::uint64_t seed = 0;   ///< feeds SomInit::random_sample only
  bool compute_sdf = true;  ///< fill FrameResult::sdf_error (not counted in time_s)
  ComponentGeometry geometry;

  /// Throws std::invalid_argument naming the offending field and value.
  void validate() const;
};

enum class InitReason : std::uint8_t {
  none,                 ///< continued from the previous frame's output
  first_frame,          ///< no previous output (first frame or after reset())
  empty_neighbourhood,  ///< a node had no points (Sec. IV.C): re-initialized by LSQ
};

enum class LostReason : std::uint8_t {
  none,
  empty_cloud,      ///< the cloud has no points at all
  all_non_finite,   ///< every point had a NaN or Inf coordinate
  too_few_points,   ///< fewer finite points than nodes
  too_many_points,  ///< more than kMaxPoints usable points
};

[[nodiscard]] std::string_view to_string(TrackerMode mode);
[[nodiscard]] std::string_view to_string(InitReason reason);
[[nodiscard]] std::string_view to_string(LostReason reason);
[[nodiscard]] TrackerMode parse_mode(std::string_view name);  ///< throws naming the value
[[nodiscard]] InitMethod parse_init(std::string_view name);   ///< throws naming the value

/// Output of one frame.
struct FrameResult {
  Nodes nodes;                       ///< M+1 reference vectors, camera frame [m] (paper_centred: moved to the ball centres)
  std::vector<std::int64_t> counts;  ///< |N_j| of the last iteration
  int iterations = 0;                ///< iterations run
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
  ~Tracker();
  Tracker(Tracker&&) noexcept;
  Tracker& operator=(Tracker&&) noexcept;

  /// Runs Algorithm 1 on one cloud. Never throws for bad data: it reports `lost`.
  FrameResult step(const Cloud& cloud);
  /// Forgets the previous output; the next frame initializes from scratch.
  void reset();

  [[nodiscard]] const TrackerParams& params() const { return params_; }
  /// Associations of the finite points of the last step's final iteration.
  [[nodiscard]] std::span<const std::int32_t> last_association() const;

 private:
  struct State;
  TrackerParams params_;
  std::unique_ptr<State> state_;
};

}  // namespace linksight
