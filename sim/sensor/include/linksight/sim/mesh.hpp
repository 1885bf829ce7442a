#pragma once
/// @file Triangle meshes of the link's component (for rendering and the simulator) and
/// a loader for mesh files of any format assimp reads.

#include <Eigen/Geometry>
#include <filesystem>
#include <string>
#include <vector>

#include "linksight/io/depth_png.hpp"
#include "linksight/io/intrinsics.hpp"
#include "linksight/tracker/geometry.hpp"

namespace linksight::sim {

/// An indexed triangle mesh. Vertices in metres; each triangle lists three vertex
/// indices counter-clockwise seen from outside (right-hand normal points outward).
struct TriangleMesh {
  std::vector<Eigen::Vector3f> vertices;
  std::vector<Eigen::Vector3i> triangles;
};

/// The component's surface in its frame K (origin at the ball centre, +Z toward the
/// next ball): a UV sphere of radius ball_radius plus a capsule of radius neck_radius
/// around the segment (0,0,0)-(0,0,neck_length). Two separate closed, outward-oriented
/// shells that overlap (their union is the component; fine for rendering). `segments`
/// is the number of slices around each axis (>= 4); each hemisphere gets segments/4
/// latitude bands. Throws std::invalid_argument for a bad geometry or segment count.
[[nodiscard]] TriangleMesh component_mesh(const ComponentGeometry& geometry, int segments = 32);

/// A box centred at the origin with the given half extents [m] (12 triangles).
[[nodiscard]] TriangleMesh box_mesh(const Eigen::Vector3d& half_extents);
/// A closed cylinder around the z axis from -half_length to +half_length [m].
[[nodiscard]] TriangleMesh cylinder_mesh(double radius, double half_length, int slices = 48);
/// A UV sphere centred at the origin; `segments` slices, segments/4 bands per hemisphere.
[[nodiscard]] TriangleMesh sphere_mesh(double radius, int segments = 48);

/// Appends `part` moved by X to `mesh`.
void append(TriangleMesh& mesh, const TriangleMesh& part,
            const Eigen::Isometry3d& X = Eigen::Isometry3d::Identity());

/// An occluder shaped like a hand on a forearm, about human size: palm centred at the
/// origin facing +-y, fingers along +z, forearm along -z (meshes/hand.obj).
[[nodiscard]] TriangleMesh hand_mesh();
/// A mug for clutter: a cylinder of radius 4 cm, 10 cm tall, standing on z = 0, with a
/// handle on +x (meshes/mug.obj).
[[nodiscard]] TriangleMesh mug_mesh();

/// How depth_surface_mesh turns a depth image back into the surface it saw.
struct DepthSurfaceParams {
  /// Invalid runs of at most this many pixels along a row or column, between valid pixels,
  /// are filled: across a discontinuity (the ends differ by more than `jump`) with the far
  /// side's depth, since the far surface goes on behind the edge where the camera left its
  /// band; otherwise (a hole) linearly.
  int max_gap_px = 40;
  double jump = 0.02;        ///< [m]
  /// The depth is smoothed by a Gaussian of this sigma [px] over neighbours within
  /// 3 `jump` (edges stay sharp), so that the camera's own noise is not baked into the surface; a
  /// Gaussian keeps a quadratic surface, so the curvature a 15x15 plane fit sees stays.
  double smoothing_px = 8.0;
  void validate() const;  ///< throws std::invalid_argument naming the field
};

/// How far behind its pixel's depth a rim pixel's splat in depth_surface_mesh sits, at the
/// pixel's centre [m]: enough that a ray meeting the mesh keeps the mesh's depth.
inline constexpr double kRimSplatBehind_m = 0.0002;

/// The surface a depth image (raw units, 0 = invalid) saw, in the camera frame C [m]: one
/// vertex per valid or filled pixel, deprojected with `intrinsics` 0.01 px off the pixel's
/// ray (so that a ray through the pixel meets a triangle's inside, not a vertex), and two
/// triangles per 2x2 block whose corners are all present and within `jump` of each other
/// (none across a discontinuity); and at every pixel with an 8-neighbour off its surface or
/// off the image, a square of its tangent plane over its own footprint, 0.2 mm behind at its
/// centre, so that the rim's rays meet the surface as the camera's did. For re-rendering a real recording's geometry
/// through the simulated camera (`linksight fidelity`): same scene, so what differs is the
/// sensor model. Throws std::invalid_argument for a size that differs from the
/// intrinsics, or no valid pixel.
[[nodiscard]] TriangleMesh depth_surface_mesh(const io::DepthImage& depth,
                                              const io::Intrinsics& intrinsics,
                                              const DepthSurfaceParams& params = {});

/// Writes `mesh` as Wavefront OBJ (v / f lines, 1-based), atomically. Each line of
/// `comment` (if any) becomes a leading "# " line. Throws linksight::io::InputError
/// naming the path when it cannot be written, std::invalid_argument for a triangle
/// index out of range.
void write_obj(const std::filesystem::path& path, const TriangleMesh& mesh,
               const std::string& comment = {});

/// Loads any mesh file assimp reads (triangulated, identical vertices joined), merging
/// all meshes of the scene with their node transforms applied. Throws
/// linksight::io::InputError("<file>: <problem>") when assimp fails or the file holds
/// no triangles.
[[nodiscard]] TriangleMesh load_mesh(const std::filesystem::path& path);

}  // namespace linksight::sim
