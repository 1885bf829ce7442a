#pragma once
// The sensor's state and its stages, shared by sensor.cpp (set-up, render's stage list)
// and sensor_cast.cpp (scene update, culling plan, cast with shadows, occlusion truth).
// Private to sim/sensor.

#include <embree3/rtcore.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "linksight/sim/sensor.hpp"
#include "linksight/sim/sensor_cull.hpp"
#include "linksight/sim/sensor_noise.hpp"
#include "pixel_draws.hpp"

namespace linksight::sim {
namespace detail {

// Instance masks: the no-occluder label pass casts with kMaskScene only.
constexpr unsigned kMaskScene = 1;
constexpr unsigned kMaskOccluder = 2;

// acos on [0, 1] to 2e-8 rad (Abramowitz & Stegun 4.4.46): a third of libm's cost.
inline double acos_unit(double x) {
  return std::sqrt(1.0 - x) *
         (1.5707963050 +
          x * (-0.2145988016 +
               x * (0.0889789874 +
                    x * (-0.0501743046 +
                         x * (0.0308918810 +
                              x * (-0.0170881256 + x * (0.0066700901 + x * -0.0012624911)))))));
}

inline void set_transform(RTCGeometry g, const Eigen::Isometry3d& X) {
  float m[12];  // 3x4 column-major
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 3; ++r) m[c * 3 + r] = static_cast<float>(X.matrix()(r, c));
  rtcSetGeometryTransform(g, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, m);
}

// Lane i of a packet: a ray from `o` along `d` over [0, tfar] with the given mask.
template <typename Vec>
inline void set_lane(RTCRay16& r, int i, const Vec& o, const Vec& d, float tfar, unsigned mask) {
  r.org_x[i] = static_cast<float>(o.x());
  r.org_y[i] = static_cast<float>(o.y());
  r.org_z[i] = static_cast<float>(o.z());
  r.dir_x[i] = static_cast<float>(d.x());
  r.dir_y[i] = static_cast<float>(d.y());
  r.dir_z[i] = static_cast<float>(d.z());
  r.tnear[i] = 0.0F;
  r.tfar[i] = tfar;
  r.mask[i] = mask;
  r.time[i] = 0.0F;
  r.flags[i] = 0;
  r.id[i] = static_cast<unsigned>(i);
}
// The same for an intersection packet, with no hit yet.
template <typename Vec>
inline void set_lane(RTCRayHit16& rh, int i, const Vec& o, const Vec& d, unsigned mask) {
  set_lane(rh.ray, i, o, d, std::numeric_limits<float>::infinity(), mask);
  rh.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
}


// Pixel i's ray direction in W, scaled so that its camera-frame z is 1: the hit
// distance t is then the depth. Jittered by the lateral noise (draws from the pixel key).
struct RayDirections {
  const io::Intrinsics* K = nullptr;
  Eigen::Matrix3f R_WC_f = Eigen::Matrix3f::Identity();
  bool jitter = false, pinhole = true;
  double sigma_px = 0, inv_fx = 1, inv_fy = 1;
  std::uint64_t frame_seed = 0;
  Eigen::Vector3f operator()(int u, int v, std::size_t pix) const {
    double du = 0, dv = 0;
    if (jitter) {
      // One 64-bit draw, a half for each axis.
      const std::uint64_t bits = mix64(pixel_key(frame_seed, pix) + kJitter * 0xD1B54A32D192ED03ull);
      du = normal32(static_cast<std::uint32_t>(bits >> 32)) * sigma_px;
      dv = normal32(static_cast<std::uint32_t>(bits)) * sigma_px;
    }
    // The pinhole case inline (it is most of the per-ray cost); distortion via deproject.
    const Eigen::Vector3f d_C =
        pinhole ? Eigen::Vector3f(static_cast<float>((u + du - K->cx) * inv_fx),
                                  static_cast<float>((v + dv - K->cy) * inv_fy), 1.0F)
                : K->deproject(u + du, v + dv, 1.0).cast<float>();
    return Eigen::Vector3f(R_WC_f * d_C);
  }
};

}  // namespace detail

// One frame's plan, made by the culling stage and read by the others.
struct FramePlan {
  std::uint64_t frame_seed = 0;
  int threads = 1;
  detail::RayDirections rays;  // the jittered rays of this frame's pixels
  Eigen::Vector3f o_Wf;        // their origin (the camera), in float as Embree takes it
  int per_row = 0;             // packets of kRayPacket pixels per image row
  long packets = 0;            // in the image
  std::vector<Eigen::AlignedBox3d> moving_W;  // world bounds: the chain, then each occluder
  // Pixels outside these rectangles cannot see anything (scene_rect), a moving body
  // (moving_rect, one per body) or the chain (chain_rect = moving_rect[0]).
  PixelRect scene_rect;
  std::vector<PixelRect> moving_rect;
  PixelRect chain_rect;
  // Shadow culling: a shadow ray from p can be blocked by a moving body only if p lies
  // inside its silhouette seen from the projector and farther than it.
  std::vector<ShadowCaster> moving_casters;
  // What to compute: `inner` gets the noise pass; the clean images (cast_rect) reach
  // kEdgeReachPx further, as far as the edge model looks, so that inner's pixels match a
  // whole-frame render.
  PixelRect inner, cast_rect;
};

struct Sensor::Impl {
  SensorParams p;
  int count = 0;
  std::vector<Occluder> occluders;
  RTCDevice device = nullptr;
  // Two top-level scenes: `top` holds what moves (chain and occluder instances), `statics`
  // the background flattened into world coordinates. A static background fills the image,
  // and one flat BVH casts faster than instances; the moving part is cast only where
  // it can be seen.
  RTCScene top = nullptr;
  RTCScene statics = nullptr;
  std::vector<RTCScene> subscenes;
  std::vector<RTCGeometry> chain;      // instance handles (owned)
  std::vector<RTCGeometry> occluding;  // instance handles (owned)
  std::vector<unsigned> chain_id, occluder_id;  // their IDs in `top`
  // By instance ID in `top`:
  std::vector<std::uint8_t> label_of;
  std::vector<Eigen::Matrix3f> R_of;
  std::vector<float> reflectance_of;
  // By geometry ID in `statics`: world bounds, reflectance, and whether the object is
  // convex (a convex body cannot shadow its own lit side, so its shadow rays skip it).
  std::vector<Eigen::AlignedBox3d> static_box;
  std::vector<float> static_reflectance;
  std::vector<bool> static_convex;
  std::vector<ShadowCaster> static_casters;  // the background's, from the fixed projector pose
  // Per-pixel scratch, kept between frames: the cast's inputs to the noise model.
  std::vector<float> cos_c, cos_p, reflect;
  std::vector<std::uint8_t> lit, label_no_occluders;
  std::vector<bool> occluder_on;  // whether each occluder's instance is enabled
  std::optional<SensorNoise> noise;  // the last stage
  Eigen::AlignedBox3d component_box;  // a component's bounds in its own frame K
  std::vector<Eigen::AlignedBox3d> occluder_box;  // each occluder's bounds in its own frame
  SensorTimes times;

  // The stages of render(), in order (sensor_cast.cpp).
  std::vector<Eigen::AlignedBox3d> update_scene(const std::vector<Eigen::Isometry3d>& X_WK, double t);
  FramePlan plan(std::vector<Eigen::AlignedBox3d> moving_W, const RenderExtent& extent,
                 std::uint64_t frame_seed) const;
  void cast(const FramePlan& f, DepthFrame& out);
  void occlusion_truth(const FramePlan& f, DepthFrame& out);
  [[nodiscard]] NoiseInput noise_input(const DepthFrame& out) const;

  ~Impl() {
    for (RTCGeometry g : chain) rtcReleaseGeometry(g);
    for (RTCGeometry g : occluding) rtcReleaseGeometry(g);
    if (top) rtcReleaseScene(top);
    if (statics) rtcReleaseScene(statics);
    for (RTCScene s : subscenes) rtcReleaseScene(s);
    if (device) rtcReleaseDevice(device);
  }

  void check(const char* what) const {
    const RTCError e = rtcGetDeviceError(device);
    if (e != RTC_ERROR_NONE)
      throw std::runtime_error(std::string("Embree error ") + std::to_string(e) + " in " + what);
  }

  RTCScene mesh_scene(const TriangleMesh& m) {
    RTCScene s = rtcNewScene(device);
    subscenes.push_back(s);
    // Watertight: no rays slip between the triangles of a curved surface.
    rtcSetSceneFlags(s, RTC_SCENE_FLAG_ROBUST);
    attach_mesh(s, m, Eigen::Isometry3f::Identity(), 0xFFFFFFFFu);
    rtcCommitScene(s);
    check("mesh scene");
    return s;
  }

  // Attaches mesh `m`, its vertices moved by X, to scene `s`; returns its geometry ID.
  unsigned attach_mesh(RTCScene s, const TriangleMesh& m, const Eigen::Isometry3f& X,
                       unsigned mask) {
    RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(
        g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), m.vertices.size()));
    auto* t = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
        g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), m.triangles.size()));
    if (!v || !t) {
      rtcReleaseGeometry(g);
      check("mesh buffers");
      throw std::runtime_error("Embree: cannot allocate mesh buffers");
    }
    for (std::size_t i = 0; i < m.vertices.size(); ++i) {
      const Eigen::Vector3f x = X * m.vertices[i];
      for (int k = 0; k < 3; ++k) v[3 * i + k] = x[k];
    }
    const auto n = static_cast<int>(m.vertices.size());
    for (std::size_t i = 0; i < m.triangles.size(); ++i) {
      for (int k = 0; k < 3; ++k) {
        const int idx = m.triangles[i][k];
        if (idx < 0 || idx >= n) {
          rtcReleaseGeometry(g);
          throw std::invalid_argument("mesh triangle index " + std::to_string(idx) +
                                      " out of range");
        }
        t[3 * i + k] = static_cast<unsigned>(idx);
      }
    }
    rtcSetGeometryMask(g, mask);
    rtcCommitGeometry(g);
    const unsigned id = rtcAttachGeometry(s, g);
    rtcReleaseGeometry(g);
    check("mesh");
    return id;
  }

  RTCGeometry instance(RTCScene sub, const Eigen::Isometry3d& X, unsigned mask,
                       std::uint8_t label, double reflectance, std::vector<unsigned>& ids) {
    RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_INSTANCE);
    rtcSetGeometryInstancedScene(g, sub);
    rtcSetGeometryTimeStepCount(g, 1);
    rtcSetGeometryMask(g, mask);
    detail::set_transform(g, X);
    rtcCommitGeometry(g);
    const unsigned id = rtcAttachGeometry(top, g);
    ids.push_back(id);
    if (label_of.size() <= id) {
      label_of.resize(id + 1, kLabelNothing);
      R_of.resize(id + 1, Eigen::Matrix3f::Identity());
      reflectance_of.resize(id + 1, 1.0F);
    }
    label_of[id] = label;
    R_of[id] = X.linear().cast<float>();
    reflectance_of[id] = static_cast<float>(reflectance);
    check("instance");
    return g;
  }

};

}  // namespace linksight::sim
