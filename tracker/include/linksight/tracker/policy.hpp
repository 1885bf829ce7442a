#pragma once
/// @file The parts a tracker mode is composed of (mode.hpp), each an interface with its
/// own settings and one source file per implementation under tracker/src/policy/:
///   init     lays the nodes out from a cloud (first frame, and on re-initialization)
///   update   one iteration's nodes from the back end's association (Eq. 11)
///   reinit   after an association, whether the evidence calls for a new init
///   output   the frame's nodes from the tracker's internal ones
/// A policy is made per Tracker (it may keep buffers) from the tracker's parameters.

#include <cstdint>
#include <memory>
#include <string_view>
#include <vector>

#include "linksight/tracker/backend.hpp"
#include "linksight/tracker/chain_fit.hpp"
#include "linksight/tracker/cloud.hpp"
#include "linksight/tracker/init.hpp"
#include "linksight/tracker/model.hpp"

namespace linksight {

struct TrackerParams;

/// Lays out `n_nodes` ordered nodes from the frame's points. `previous`: the nodes before a
/// re-initialization (to keep their order), nullptr on the first frame.
class InitPolicy {
 public:
  virtual ~InitPolicy() = default;
  [[nodiscard]] virtual Nodes init(const PointsView& points, int n_nodes,
                                   const Nodes* previous) const = 0;
};

/// What a frame may bring beside its points (Tracker::step), for a whole-frame fit.
struct FrameExtras {
  const Eigen::Isometry3d* X_CB = nullptr;  ///< the base's pose (BasePriorParams), or none
  const DepthView* depth = nullptr;         ///< the frame's depth image, or none
};

/// What a whole-frame fit (UpdatePolicy::fit_frame) did.
struct FrameFit {
  bool reinit = false;  ///< the output came from a re-initialization
  int passes = 0;       ///< passes over the frame's points
};

/// One iteration: new nodes from the association the back end has just made (`acc`; the
/// per-point association is `backend.association()`, read back only when asked).
/// Returns the largest node move [m], for TrackerParams::tolerance.
class UpdatePolicy {
 public:
  virtual ~UpdatePolicy() = default;
  virtual double update(const PointsView& points, const Accumulation& acc, Backend& backend,
                        Nodes& nodes) const = 0;
  /// True for a policy that fits a whole frame at once (chain-fit): the tracker then calls
  /// fit_frame once per frame, with no back-end association and no iterations around it.
  [[nodiscard]] virtual bool fits_frame() const { return false; }
  /// The frame's nodes from the previous frame's (`nodes`, updated in place), or from an
  /// initialization's when `restarted` (first frame, re-initialization: nothing earlier
  /// frames said holds). `counts`: the points each node accounts for (nodes.size()).
  /// The policy may re-initialize from `init` on its own evidence. `extras`: the base's
  /// pose (TrackerParams::base_prior has its σ) and the depth image, when known. `backend`:
  /// the tracker's, whose device may run the passes (Backend::chain_pass_device).
  virtual FrameFit fit_frame(const PointsView& points, bool restarted, const InitPolicy& init,
                             const FrameExtras& extras, Backend& backend, Nodes& nodes,
                             std::vector<std::int64_t>& counts);
};

/// After an association (not in the frame that just initialized): the node whose
/// evidence calls for a re-initialization, or -1.
class ReinitTrigger {
 public:
  virtual ~ReinitTrigger() = default;
  [[nodiscard]] virtual int fired(const Accumulation& acc) const = 0;
};

/// The frame's output (FrameResult::nodes) from the tracker's nodes, which the next frame
/// starts from and which stay as they are.
class OutputPolicy {
 public:
  virtual ~OutputPolicy() = default;
  [[nodiscard]] virtual Nodes output(const Nodes& nodes) const = 0;
};

/// A named policy and how to make it from the tracker's parameters (which hold each
/// policy's settings in TrackerParams::policy).
template <class Policy>
struct PolicyRef {
  std::string_view name;
  std::unique_ptr<Policy> (*make)(const TrackerParams& params);
};

// ---- settings of the policies that have any (in TrackerParams::policy) ----

/// The accelerated-SOM baseline's initialization (Croom 2010 / Baader 1994).
struct SomInitParams {
  SomInit method = SomInit::straight_line;
  std::uint64_t seed = 0;  ///< feeds SomInit::random_sample only (the scene's, not a key)
  /// The key in a scene's `tracker` block.
  template <class Archive>
  void fields(Archive& ar) {
    ar("som_init", method, parse_som_init);
  }
  void validate() const {}
};

/// A SOM node is the mean of the surface points nearest it: on a ball seen from afar,
/// the mean of its visible cap, which (sampled evenly over the image disc) lies
/// 2/3 r in front of the centre along the viewing ray.
inline constexpr double kCentreOffset = 2.0 / 3.0;  ///< of the ball radius

/// Output moved from the seen surface to the ball centres (not in the paper).
struct CentreOffsetParams {
  double fraction = kCentreOffset;  ///< of the ball radius, along each node's viewing ray
  template <class Archive>
  void fields(Archive& ar) {
    ar("fraction", fraction, fields::in(0, 1));
  }
  void validate() const;  ///< throws fields::FieldError naming the key
};

/// Every policy's settings; a mode reads those of its own policies.
struct PolicyParams {
  InitParams lsq_init;               ///< init `lsq` (Eqs. 9-10)
  SomInitParams som_init;            ///< init `som`
  CentreOffsetParams centre_offset;  ///< output `centre-offset`
  ChainFitParams chain_fit;          ///< update `chain-fit` (cone_limit: the chain's)
  void validate() const;             ///< throws std::invalid_argument naming the field
};

// ---- the policies (one file each in tracker/src/policy/) ----

std::unique_ptr<InitPolicy> make_init_lsq(const TrackerParams& params);
std::unique_ptr<InitPolicy> make_init_som(const TrackerParams& params);
std::unique_ptr<InitPolicy> make_init_lsq_centred(const TrackerParams& params);
std::unique_ptr<UpdatePolicy> make_update_som_mean(const TrackerParams& params);
std::unique_ptr<UpdatePolicy> make_update_chain_fit(const TrackerParams& params);
std::unique_ptr<ReinitTrigger> make_reinit_empty_neighbourhood(const TrackerParams& params);
std::unique_ptr<ReinitTrigger> make_reinit_never(const TrackerParams& params);
std::unique_ptr<OutputPolicy> make_output_surface(const TrackerParams& params);
std::unique_ptr<OutputPolicy> make_output_centre_offset(const TrackerParams& params);
std::unique_ptr<OutputPolicy> make_output_centres(const TrackerParams& params);

/// LSQ polynomial init (Sec. IV.A, Eqs. 9-10; settings policy.lsq_init), oriented to the
/// previous nodes on re-initialization.
inline constexpr PolicyRef<InitPolicy> kInitLsq{"lsq", &make_init_lsq};
/// LSQ init, each node then moved kCentreOffset r further along its viewing ray: a start
/// near the ball centres for a model fit (settings policy.lsq_init).
inline constexpr PolicyRef<InitPolicy> kInitLsqCentred{"lsq-centred", &make_init_lsq_centred};
/// The baseline's straight-line or random-sample init (settings policy.som_init).
inline constexpr PolicyRef<InitPolicy> kInitSom{"som", &make_init_som};
/// Each node moves to the mean of the points associated with it (Eq. 12).
inline constexpr PolicyRef<UpdatePolicy> kUpdateSomMean{"som-mean", &make_update_som_mean};
/// Fires when a node's neighbourhood is empty (Sec. IV.C).
inline constexpr PolicyRef<ReinitTrigger> kReinitEmptyNeighbourhood{
    "empty-neighbourhood", &make_reinit_empty_neighbourhood};
/// The nodes as a chain of components one pitch apart, fitted to the points by their
/// distance to the component surfaces (chain_fit.hpp; settings policy.chain_fit). Needs
/// nodes = count + 1.
inline constexpr PolicyRef<UpdatePolicy> kUpdateChainFit{"chain-fit", &make_update_chain_fit};
/// Never fires.
inline constexpr PolicyRef<ReinitTrigger> kReinitNever{"never", &make_reinit_never};
/// The nodes as they are: on the seen surface.
inline constexpr PolicyRef<OutputPolicy> kOutputSurface{"surface", &make_output_surface};
/// The nodes as the fit has them: ball centres and the tip node.
inline constexpr PolicyRef<OutputPolicy> kOutputCentres{"centres", &make_output_centres};
/// Each node moved policy.centre_offset.fraction of the ball radius further from the
/// camera along its viewing ray (settings policy.centre_offset).
inline constexpr PolicyRef<OutputPolicy> kOutputCentreOffset{"centre-offset",
                                                             &make_output_centre_offset};

}  // namespace linksight
