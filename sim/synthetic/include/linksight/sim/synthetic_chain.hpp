#pragma once
/// @file Analytic chain clouds with ground truth: the camera-facing surfaces of the
/// link's balls and necks, self-occlusion by balls, axial Gaussian noise. Used by the
/// tests and by `linksight synth` until the Bullet/Embree simulator replaces it.

#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "linksight/tracker/cloud.hpp"
#include "linksight/tracker/geometry.hpp"
#include "linksight/tracker/model.hpp"

namespace linksight::sim {

enum class ChainShape { straight, c_shape, s_shape };

/// Bend angle [rad] at each joint (count-1 joints): 0; +bend everywhere; +bend on the
/// first half and -bend on the second.
[[nodiscard]] std::vector<double> shape_bends(ChainShape shape, int count, double bend);

/// True nodes: the `geometry.count` ball centres, then the tip point one pitch beyond
/// the last ball along its axis (count+1 points) [m, camera frame]. The chain starts at
/// the origin of B, leaves along B's +x and bends about B's z by `bends[k]` at joint k.
[[nodiscard]] Nodes chain_nodes(const ComponentGeometry& geometry, const std::vector<double>& bends,
                                const Eigen::Isometry3d& X_CB);

struct SurfaceSampling {
  int samples_per_ball = 1200;  ///< drawn over the whole sphere; about half face the camera
  int samples_per_neck = 250;   ///< drawn over the neck's cylinder
  bool necks = true;            ///< sample neck surfaces too
  double noise_sigma = 0.0;     ///< axial (along the ray) Gaussian noise [m]
  std::vector<int> hidden;      ///< components not rendered (as if occluded)
  std::uint64_t seed = 1;
  void validate() const;  ///< throws std::invalid_argument naming the field
};

/// Camera at the origin looking down +z. Deterministic in `sampling.seed`.
[[nodiscard]] Cloud sample_visible_surface(const Nodes& nodes, const ComponentGeometry& geometry,
                                           const SurfaceSampling& sampling);

/// The demo sequence's motion: the link bends from straight to C to S while its base
/// sways, about 0.6 m in front of the camera. Truth nodes of frame `frame` at `fps`.
[[nodiscard]] Nodes demo_nodes(const ComponentGeometry& geometry, int frame, double fps);

}  // namespace linksight::sim
