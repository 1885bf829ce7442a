#include "linksight/sim/sensor.hpp"

#include <embree3/rtcore.h>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

#include "linksight/tracker/seed.hpp"

namespace linksight::sim {
namespace {

// Instance masks: the no-occluder label pass casts with kMaskScene only.
constexpr unsigned kMaskScene = 1;
constexpr unsigned kMaskOccluder = 2;
constexpr int kPacket = 16;
// How far from a pixel the edge model looks for a discontinuity [px] (its 2-px band).
constexpr int kEdgeReach = 2;

// Counter-based draws: a (key, stream) pair always gives the same number, whichever
// thread asks, so noise does not depend on the thread count.
double uniform(std::uint64_t key, std::uint64_t stream) {
  return unit_interval(mix64(key + stream * 0xD1B54A32D192ED03ull));
}
// N(0, 1) by the inverse CDF (Acklam's rational approximation, relative error 1.2e-9):
// one uniform per draw and no transcendental call in the central 95%.
double inverse_normal_cdf(double p) {
  static constexpr double a[] = {-3.969683028665376e+01, 2.209460984245205e+02,
                                 -2.759285104469687e+02, 1.383577518672690e+02,
                                 -3.066479806614716e+01, 2.506628277459239e+00};
  static constexpr double b[] = {-5.447609879822406e+01, 1.615858368580409e+02,
                                 -1.556989798598866e+02, 6.680131188771972e+01,
                                 -1.328068155288572e+01};
  static constexpr double c[] = {-7.784894002430293e-03, -3.223964580411365e-01,
                                 -2.400758277161838e+00, -2.549732539343734e+00,
                                 4.374664141464968e+00,  2.938163982698783e+00};
  static constexpr double d[] = {7.784695709041462e-03, 3.224671290700398e-01,
                                 2.445134137142996e+00, 3.754408661907416e+00};
  constexpr double low = 0.02425;
  if (p < low || p > 1 - low) {
    const double q = std::sqrt(-2 * std::log(p < low ? p : 1 - p));
    const double x = (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
                     ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1);
    return p < low ? x : -x;
  }
  const double q = p - 0.5, r = q * q;
  return (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
         (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1);
}
// The inverse CDF tabulated at 4096 equal steps of p; linear interpolation inside, the
// exact rational form in the outer two bins (|x| > 3.5). Interpolation error < 1e-4.
struct NormalTable {
  static constexpr int kBins = 4096;
  double x[kBins + 1];
  NormalTable() {
    for (int i = 1; i < kBins; ++i) x[i] = inverse_normal_cdf(static_cast<double>(i) / kBins);
    x[0] = x[kBins] = 0.0;  // unused: the outer bins use the exact form
  }
};
const NormalTable kNormalTable;

// N(0, 1) from 32 random bits: the table's bin is the top 12 bits, the position inside it
// the other 20. Bits are the centre of one of 2^32 equal bins: p is never 0 or 1, and the
// extreme draw is 6.3 sigma.
double normal32(std::uint32_t bits) {
  static_assert(NormalTable::kBins == 1 << 12);
  const int i = static_cast<int>(bits >> 20);
  if (i == 0 || i == NormalTable::kBins - 1)
    return inverse_normal_cdf((static_cast<double>(bits) + 0.5) * 0x1.0p-32);
  const double f = (static_cast<double>(bits & 0xFFFFFu) + 0.5) * 0x1.0p-20;
  return kNormalTable.x[i] + f * (kNormalTable.x[i + 1] - kNormalTable.x[i]);
}
double normal(std::uint64_t key, std::uint64_t stream) {
  return normal32(static_cast<std::uint32_t>(mix64(key + stream * 0xD1B54A32D192ED03ull) >> 32));
}
// The largest |normal32|: the draw from bits 0.
const double kMaxNormal32 = -inverse_normal_cdf(0.5 * 0x1.0p-32);
// Pixel `pix`'s key: the splitmix64 sequence of the frame's seed, indexed by pixel.
std::uint64_t pixel_key(std::uint64_t frame_seed, std::size_t pix) {
  return mix64(frame_seed + (pix + 1) * 0x9E3779B97F4A7C15ull);
}

// acos on [0, 1] to 2e-8 rad (Abramowitz & Stegun 4.4.46): a third of libm's cost.
double acos_unit(double x) {
  return std::sqrt(1.0 - x) *
         (1.5707963050 +
          x * (-0.2145988016 +
               x * (0.0889789874 +
                    x * (-0.0501743046 +
                         x * (0.0308918810 +
                              x * (-0.0170881256 + x * (0.0066700901 + x * -0.0012624911)))))));
}

// A PixelBox that packets can be tested against. Its bounds may lie one pixel outside the
// image (reachable() clamps to [-1, size]).
struct PixelRect : PixelBox {
  // Whether the 16 pixels (u, v) ... (u + 15, v) of a packet reach into the rectangle.
  [[nodiscard]] bool touches(int u, int v) const {
    return v >= v0 && v <= v1 && u + kPacket - 1 >= u0 && u <= u1;
  }
};
// `r` grown by `by` pixels each way, clipped to a W x H image; empty stays empty.
PixelRect grown(const PixelRect& r, int by, int W, int H) {
  if (r.empty()) return {};
  return {{std::max(0, r.u0 - by), std::min(W - 1, r.u1 + by), std::max(0, r.v0 - by),
           std::min(H - 1, r.v1 + by)}};
}
// The pixels whose rays, jittered by at most `margin_px`, can reach the world box
// [lo, hi]. A pinhole ray reaches the box only if it passes inside the box's projection,
// and the projection of a convex body lies in the hull of its corners' projections.
// The whole image when that does not hold: a corner at or behind the camera plane, or a
// distorted camera.
PixelRect reachable(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                    const Eigen::Isometry3d& X_WC, const io::Intrinsics& K, double margin_px) {
  const PixelRect all{{0, K.width - 1, 0, K.height - 1}};
  if (!(lo.array() <= hi.array()).all()) return {};  // nothing in the scene
  if (K.model != io::Distortion::none) return all;
  const Eigen::Isometry3d X_CW = X_WC.inverse();
  double u_min = std::numeric_limits<double>::infinity(), u_max = -u_min;
  double v_min = u_min, v_max = -u_min;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d p_W((c & 1) ? hi.x() : lo.x(), (c & 2) ? hi.y() : lo.y(),
                              (c & 4) ? hi.z() : lo.z());
    const Eigen::Vector3d p_C = X_CW * p_W;
    if (!(p_C.z() > 1e-6)) return all;
    const double u = K.fx * p_C.x() / p_C.z() + K.cx, v = K.fy * p_C.y() / p_C.z() + K.cy;
    u_min = std::min(u_min, u);
    u_max = std::max(u_max, u);
    v_min = std::min(v_min, v);
    v_max = std::max(v_max, v);
  }
  // A pixel's ray passes through (u + du, v + dv): keep u within margin of the projection.
  const auto clamp_to = [](double x, int hi_px) {
    return static_cast<int>(std::clamp(x, -1.0, static_cast<double>(hi_px) + 1));
  };
  return {{clamp_to(std::floor(u_min - margin_px), K.width - 1),
           clamp_to(std::ceil(u_max + margin_px), K.width - 1),
           clamp_to(std::floor(v_min - margin_px), K.height - 1),
           clamp_to(std::ceil(v_max + margin_px), K.height - 1)}};
}

// A body that may cast a projector shadow, seen from the projector: the bounds of its
// silhouette on the projector's z = 1 plane and its least distance from the projector.
// A segment from p to the projector meets the body only if p projects inside the
// silhouette (the segment's points all project onto p) and p is farther than the body.
struct Caster {
  float x0 = -std::numeric_limits<float>::infinity(), x1 = -x0, y0 = x0, y1 = x1;
  float dist2 = 0;  // squared least distance [m^2]
  bool everywhere = true;  // a corner at or behind the projector plane: no silhouette bound

  static Caster of(const Eigen::AlignedBox3d& box_W, const Eigen::Matrix3d& R_WP,
                   const Eigen::Vector3d& p_WP) {
    Caster c;
    if (box_W.isEmpty()) {  // an absent body blocks nothing
      c.everywhere = false;
      c.dist2 = std::numeric_limits<float>::infinity();
      return c;
    }
    double x0 = std::numeric_limits<double>::infinity(), x1 = -x0, y0 = x0, y1 = -x0;
    for (int k = 0; k < 8; ++k) {
      const Eigen::Vector3d q =
          R_WP.transpose() * (box_W.corner(static_cast<Eigen::AlignedBox3d::CornerType>(k)) - p_WP);
      if (!(q.z() > 1e-6)) return c;
      x0 = std::min(x0, q.x() / q.z());
      x1 = std::max(x1, q.x() / q.z());
      y0 = std::min(y0, q.y() / q.z());
      y1 = std::max(y1, q.y() / q.z());
    }
    // Margins for the float arithmetic of the test and of the shadow ray's origin
    // (1e-5 m off the surface): 1e-4 on the plane, 1 mm in distance.
    constexpr double kSlack = 1e-4;
    c.everywhere = false;
    c.x0 = static_cast<float>(x0 - kSlack);
    c.x1 = static_cast<float>(x1 + kSlack);
    c.y0 = static_cast<float>(y0 - kSlack);
    c.y1 = static_cast<float>(y1 + kSlack);
    const double d = std::max(0.0, box_W.exteriorDistance(p_WP) - 1e-3);
    c.dist2 = static_cast<float>(d * d);
    return c;
  }
  /// q: the ray's start in the projector's frame (z along the optical axis).
  [[nodiscard]] bool may_block(const Eigen::Vector3f& q) const {
    if (everywhere) return true;
    if (q.squaredNorm() <= dist2) return false;
    if (!(q.z() > 0)) return true;  // beside or behind the projector: no silhouette test
    const float x = q.x() / q.z(), y = q.y() / q.z();
    return x >= x0 && x <= x1 && y >= y0 && y <= y1;
  }
};

enum Stream : std::uint64_t { kJitter = 0, kAxial = 2, kEdge = 4, kFlying = 5, kMix = 6 };

// A normalized Gaussian of standard deviation s [px], cut at 3 s, with sum k^2 = 1: one
// 1-D pass keeps unit white noise at unit variance (at the image border the kernel is cut
// and the variance a little lower).
std::vector<float> unit_variance_gaussian(double s) {
  const int R = static_cast<int>(std::ceil(3 * s));
  std::vector<double> g(static_cast<std::size_t>(2 * R + 1));
  double sum2 = 0;
  for (int i = -R; i <= R; ++i) {
    g[static_cast<std::size_t>(i + R)] = std::exp(-0.5 * i * i / (s * s));
    sum2 += g[static_cast<std::size_t>(i + R)] * g[static_cast<std::size_t>(i + R)];
  }
  std::vector<float> k(g.size());
  for (std::size_t i = 0; i < g.size(); ++i) k[i] = static_cast<float>(g[i] / std::sqrt(sum2));
  return k;
}

// The separable blur of a w x h row-major field, one pass each way. Every output sums
// kernel[i + R] * input over the taps inside the field, i ascending from 0, the same float
// operations in the same order whatever the thread count; the loops run along rows, so
// the compiler vectorizes them and the column pass reads whole rows.
void blur_rows(const std::vector<float>& src, std::vector<float>& dst, int w, int h,
               const std::vector<float>& kernel, int threads) {
  const int R = static_cast<int>(kernel.size() / 2);
#pragma omp parallel for schedule(static) num_threads(threads)
  for (int y = 0; y < h; ++y) {
    const float* in = src.data() + static_cast<std::size_t>(y) * w;
    float* out = dst.data() + static_cast<std::size_t>(y) * w;
    std::fill(out, out + w, 0.0F);
    for (int i = -R; i <= R; ++i) {
      const float k = kernel[static_cast<std::size_t>(i + R)];
      for (int x = std::max(0, -i); x < std::min(w, w - i); ++x) out[x] += k * in[x + i];
    }
  }
}
void blur_columns(const std::vector<float>& src, std::vector<float>& dst, int w, int h,
                  const std::vector<float>& kernel, int threads) {
  const int R = static_cast<int>(kernel.size() / 2);
#pragma omp parallel for schedule(static) num_threads(threads)
  for (int y = 0; y < h; ++y) {
    float* out = dst.data() + static_cast<std::size_t>(y) * w;
    std::fill(out, out + w, 0.0F);
    for (int i = std::max(-R, -y); i <= std::min(R, h - 1 - y); ++i) {
      const float k = kernel[static_cast<std::size_t>(i + R)];
      const float* in = src.data() + static_cast<std::size_t>(y + i) * w;
      for (int x = 0; x < w; ++x) out[x] += k * in[x];
    }
  }
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void set_transform(RTCGeometry g, const Eigen::Isometry3d& X) {
  float m[12];  // 3x4 column-major
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 3; ++r) m[c * 3 + r] = static_cast<float>(X.matrix()(r, c));
  rtcSetGeometryTransform(g, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, m);
}

// Lane i of a packet: a ray from `o` along `d` over [0, tfar] with the given mask.
template <typename Vec>
void set_lane(RTCRay16& r, int i, const Vec& o, const Vec& d, float tfar, unsigned mask) {
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
void set_lane(RTCRayHit16& rh, int i, const Vec& o, const Vec& d, unsigned mask) {
  set_lane(rh.ray, i, o, d, std::numeric_limits<float>::infinity(), mask);
  rh.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
}

}  // namespace

void Shape::validate() const {
  switch (kind) {
    case Kind::box:
      if (!(half_extents.minCoeff() > 0) || !half_extents.allFinite())
        throw std::invalid_argument("shape half_extents must all be > 0");
      break;
    case Kind::cylinder:
      if (!(half_length > 0) || !std::isfinite(half_length))
        throw std::invalid_argument("shape half_length = " + std::to_string(half_length) +
                                    ": must be > 0");
      [[fallthrough]];
    case Kind::sphere:
      if (!(radius > 0) || !std::isfinite(radius))
        throw std::invalid_argument("shape radius = " + std::to_string(radius) + ": must be > 0");
      break;
    case Kind::mesh:
      if (mesh.empty() && (!mesh_data || mesh_data->triangles.empty()))
        throw std::invalid_argument("shape mesh: no file given");
      if (!(scale > 0) || !std::isfinite(scale))
        throw std::invalid_argument("shape scale = " + std::to_string(scale) + ": must be > 0");
      break;
  }
}

TriangleMesh Shape::triangles() const {
  validate();
  switch (kind) {
    case Kind::box:
      return box_mesh(half_extents);
    case Kind::cylinder:
      return cylinder_mesh(radius, half_length);
    case Kind::sphere:
      return sphere_mesh(radius);
    case Kind::mesh: {
      TriangleMesh m = mesh.empty() ? *mesh_data : load_mesh(mesh);  // names a bad file
      for (Eigen::Vector3f& v : m.vertices) v *= static_cast<float>(scale);
      return m;
    }
  }
  throw std::invalid_argument("shape: unknown kind");
}

void SensorParams::validate() const {
  camera.validate();
  noise.validate();
  if (!(chain_reflectance >= 0) || !std::isfinite(chain_reflectance))
    throw std::invalid_argument("sensor chain_reflectance = " + std::to_string(chain_reflectance) +
                                ": must be >= 0");
  if (component_segments < 4 || component_segments > 1024)
    throw std::invalid_argument("sensor component_segments = " +
                                std::to_string(component_segments) + ": must be in [4, 1024]");
  if (threads < 0)
    throw std::invalid_argument("sensor threads = " + std::to_string(threads) + ": must be >= 0");
}

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
  std::vector<Caster> static_casters;  // the background's, from the fixed projector pose
  // Per-pixel scratch, kept between frames.
  std::vector<float> cos_c, cos_p, reflect;
  std::vector<std::uint8_t> lit, hole, label_no_occluders;
  std::vector<bool> occluder_on;  // whether each occluder's instance is enabled
  std::vector<float> blur_kernel;              // correlated axial noise, set at set-up
  std::vector<float> white, blurred, field;  // its per-frame buffers (see render)
  std::vector<int> blob;                     // the hole being grown (see render)
  std::vector<std::uint32_t> blob_stamp;     // per pixel: the id of the last blob it joined
  std::uint32_t blob_id = 0;
  Eigen::AlignedBox3d component_box;  // a component's bounds in its own frame K
  std::vector<Eigen::AlignedBox3d> occluder_box;  // each occluder's bounds in its own frame
  SensorTimes times;

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
    set_transform(g, X);
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

Sensor::Sensor(const SensorParams& params, const ComponentGeometry& geometry,
               std::vector<Occluder> occluders, std::vector<BackgroundObject> background)
    : impl_(std::make_unique<Impl>()) {
  params.validate();
  geometry.validate();
  if (geometry.count > kLabelOccluder0)
    throw std::invalid_argument("sensor: at most " + std::to_string(kLabelOccluder0) +
                                " components can be labelled");
  if (static_cast<int>(occluders.size()) > kMaxOccluders)
    throw std::invalid_argument("sensor: at most " + std::to_string(kMaxOccluders) + " occluders");
  Impl& m = *impl_;
  m.p = params;
  m.count = geometry.count;
  m.occluders = std::move(occluders);
  if (params.noise.axial.correlation_px > 0)
    m.blur_kernel = unit_variance_gaussian(params.noise.axial.correlation_px);
  // Meshes first: a missing file fails before Embree is set up.
  const TriangleMesh component = component_mesh(geometry, params.component_segments);
  std::vector<TriangleMesh> occluder_meshes, background_meshes;
  for (std::size_t k = 0; k < m.occluders.size(); ++k) {
    const Occluder& o = m.occluders[k];
    if (std::isnan(o.from_s) || std::isnan(o.to_s) || !(o.from_s < o.to_s))
      throw std::invalid_argument("occluder " + std::to_string(k) + ": from_s = " +
                                  std::to_string(o.from_s) + ", to_s = " +
                                  std::to_string(o.to_s) + ": need from_s < to_s");
    try {
      occluder_meshes.push_back(m.occluders[k].shape.triangles());
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("occluder " + std::to_string(k) + ": " + e.what());
    }
  }
  for (std::size_t k = 0; k < background.size(); ++k) {
    try {
      background_meshes.push_back(background[k].shape.triangles());
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("background object " + std::to_string(k) + ": " + e.what());
    }
  }
  m.device = rtcNewDevice(nullptr);
  if (!m.device) throw std::runtime_error("Embree: cannot create a device");
  m.top = rtcNewScene(m.device);
  rtcSetSceneFlags(m.top, RTC_SCENE_FLAG_DYNAMIC);
  rtcSetSceneBuildQuality(m.top, RTC_BUILD_QUALITY_LOW);
  RTCScene comp = m.mesh_scene(component);
  for (const Eigen::Vector3f& v : component.vertices) m.component_box.extend(v.cast<double>());
  for (int c = 0; c < m.count; ++c) {
    m.chain.push_back(m.instance(comp, Eigen::Isometry3d::Identity(), kMaskScene,
                                 static_cast<std::uint8_t>(c), params.chain_reflectance, m.chain_id));
  }
  for (std::size_t k = 0; k < m.occluders.size(); ++k) {
    Eigen::AlignedBox3d box;
    for (const Eigen::Vector3f& v : occluder_meshes[k].vertices) box.extend(v.cast<double>());
    m.occluder_box.push_back(box);
    m.occluding.push_back(m.instance(m.mesh_scene(occluder_meshes[k]),
                                     m.occluders[k].path.pose(0.0), kMaskOccluder,
                                     static_cast<std::uint8_t>(kLabelOccluder0 + k),
                                     m.occluders[k].reflectance, m.occluder_id));
    m.occluder_on.push_back(true);
  }
  m.statics = rtcNewScene(m.device);
  rtcSetSceneFlags(m.statics, RTC_SCENE_FLAG_ROBUST);
  for (std::size_t k = 0; k < background.size(); ++k) {
    const Eigen::Isometry3f X_WO = background[k].X_WO.cast<float>();
    const unsigned id = m.attach_mesh(m.statics, background_meshes[k], X_WO, kMaskScene);
    if (m.static_box.size() <= id) {
      m.static_box.resize(id + 1);
      m.static_reflectance.resize(id + 1, 1.0F);
      m.static_convex.resize(id + 1, false);
    }
    Eigen::AlignedBox3d box;
    for (const Eigen::Vector3f& v : background_meshes[k].vertices)
      box.extend((X_WO * v).cast<double>());
    m.static_box[id] = box;
    m.static_reflectance[id] = static_cast<float>(background[k].reflectance);
    m.static_convex[id] = background[k].shape.kind != Shape::Kind::mesh;
  }
  // The camera and the projector do not move: the background's silhouettes are set-up.
  const Eigen::Vector3d P_W =
      params.camera.X_WC * Eigen::Vector3d(params.noise.shadow.baseline, 0, 0);
  for (const Eigen::AlignedBox3d& box : m.static_box)
    m.static_casters.push_back(Caster::of(box, params.camera.X_WC.linear(), P_W));
  rtcCommitScene(m.top);
  rtcCommitScene(m.statics);
  m.check("scene");
}

Sensor::~Sensor() = default;

const SensorParams& Sensor::params() const { return impl_->p; }
const SensorTimes& Sensor::last_times() const { return impl_->times; }

DepthFrame Sensor::render(const std::vector<Eigen::Isometry3d>& X_WK, double t,
                          std::uint64_t seed, std::uint64_t frame,
                          const RenderExtent& extent) {
  DepthFrame out;
  render(X_WK, t, seed, frame, out, extent);
  return out;
}

void Sensor::render(const std::vector<Eigen::Isometry3d>& X_WK, double t, std::uint64_t seed,
                    std::uint64_t frame, DepthFrame& out, const RenderExtent& extent) {
  Impl& m = *impl_;
  if (static_cast<int>(X_WK.size()) != m.count) {
    throw std::invalid_argument("sensor render: " + std::to_string(X_WK.size()) +
                                " component poses for a chain of " + std::to_string(m.count));
  }
  if (extent.margin_px < 0)
    throw std::invalid_argument("sensor render: extent margin_px = " +
                                std::to_string(extent.margin_px) + ": must be >= 0");
  const auto t0 = std::chrono::steady_clock::now();
  for (int c = 0; c < m.count; ++c) {
    set_transform(m.chain[c], X_WK[c]);
    rtcCommitGeometry(m.chain[c]);
    m.R_of[m.chain_id[c]] = X_WK[c].linear().cast<float>();
  }
  std::vector<Eigen::AlignedBox3d> moving_W;  // world bounds: the chain, then each occluder
  moving_W.emplace_back();
  for (int c = 0; c < m.count; ++c)
    for (int k = 0; k < 8; ++k)
      moving_W[0].extend(X_WK[c] * m.component_box.corner(static_cast<Eigen::AlignedBox3d::CornerType>(k)));
  for (std::size_t k = 0; k < m.occluders.size(); ++k) {
    moving_W.emplace_back();  // empty while absent: no rectangle, never casts a shadow
    if (!m.occluders[k].present(t)) {
      if (m.occluder_on[k]) rtcDisableGeometry(m.occluding[k]);
      m.occluder_on[k] = false;
      continue;
    }
    if (!m.occluder_on[k]) rtcEnableGeometry(m.occluding[k]);
    m.occluder_on[k] = true;
    const Eigen::Isometry3d X_WO = m.occluders[k].path.pose(t);
    for (int c = 0; c < 8; ++c)
      moving_W.back().extend(X_WO * m.occluder_box[k].corner(static_cast<Eigen::AlignedBox3d::CornerType>(c)));
    set_transform(m.occluding[k], X_WO);
    rtcCommitGeometry(m.occluding[k]);
    m.R_of[m.occluder_id[k]] = X_WO.linear().cast<float>();
  }
  rtcCommitScene(m.top);
  m.check("scene update");
  m.times.scene = seconds_since(t0);

  const io::Intrinsics& K = m.p.camera.intrinsics;
  const NoiseParams& noise = m.p.noise;
  const int W = K.width, H = K.height;
  const std::size_t n = static_cast<std::size_t>(W) * H;
  out.width = W;
  out.height = H;
  out.depth.width = W;
  out.depth.height = H;
  out.depth.data.assign(n, 0);
  out.depth_m.assign(n, 0.0F);
  out.depth_clean_m.assign(n, 0.0F);
  out.label.assign(n, kLabelNothing);
  out.incidence.assign(n, std::numeric_limits<float>::quiet_NaN());
  // Read at hit pixels only, which the cast writes; lit defaults to 1 (only shadows clear it).
  m.cos_c.resize(n);
  m.cos_p.resize(n);
  m.reflect.resize(n);
  m.lit.assign(n, 1);
  const std::uint64_t frame_seed = derive_seed(derive_seed(seed, "sensor"), frame);
  const int threads = m.p.threads > 0 ? m.p.threads : omp_get_max_threads();

  const Eigen::Matrix3d R_WC = m.p.camera.X_WC.linear();
  const Eigen::Vector3d o_W = m.p.camera.X_WC.translation();
  const Eigen::Vector3d P_W = m.p.camera.X_WC * Eigen::Vector3d(noise.shadow.baseline, 0, 0);
  const bool jitter = noise.lateral.enabled && noise.lateral.sigma_px > 0;
  const bool shadows = noise.shadow.enabled;
  const int per_row = (W + kPacket - 1) / kPacket;
  const long packets = static_cast<long>(per_row) * H;
  // Rays in float, as Embree takes them.
  const Eigen::Matrix3f R_WC_f = R_WC.cast<float>();
  const Eigen::Vector3f o_Wf = o_W.cast<float>(), z_f = Eigen::Vector3f::UnitZ();
  const Eigen::Vector3f P_Wf = P_W.cast<float>();
  const bool pinhole = K.model == io::Distortion::none;
  const double inv_fx = 1.0 / K.fx, inv_fy = 1.0 / K.fy;
  // Ray direction of pixel i in W, scaled so that its camera-frame z is 1: the hit
  // distance t is then the depth.
  auto direction = [&](int u, int v, std::size_t pix) {
    double du = 0, dv = 0;
    if (jitter) {
      // One 64-bit draw, a half for each axis.
      const std::uint64_t bits = mix64(pixel_key(frame_seed, pix) + kJitter * 0xD1B54A32D192ED03ull);
      du = normal32(static_cast<std::uint32_t>(bits >> 32)) * noise.lateral.sigma_px;
      dv = normal32(static_cast<std::uint32_t>(bits)) * noise.lateral.sigma_px;
    }
    // The pinhole case inline (it is most of the per-ray cost); distortion via deproject.
    const Eigen::Vector3f d_C =
        pinhole ? Eigen::Vector3f(static_cast<float>((u + du - K.cx) * inv_fx),
                                  static_cast<float>((v + dv - K.cy) * inv_fy), 1.0F)
                : K.deproject(u + du, v + dv, 1.0).cast<float>();
    return Eigen::Vector3f(R_WC_f * d_C);
  };
  // Inactive shadow lanes still hold a finite ray: Embree's packet path reads them too.
  alignas(64) RTCRay16 shadow_idle;
  for (int i = 0; i < kPacket; ++i)
    set_lane(shadow_idle, i, o_Wf, z_f, 0.0F, 0xFFFFFFFFu);

  // Culling: pixels outside these rectangles cannot see anything (scene_rect), a moving
  // body (moving_rect, one per body) or the chain (chain_rect).
  const double margin_px = 1.0 + (jitter ? noise.lateral.sigma_px * kMaxNormal32 : 0.0);
  const PixelRect everything{{0, W - 1, 0, H - 1}};
  PixelRect scene_rect = everything;
  std::vector<PixelRect> moving_rect(moving_W.size(), everything);
  const bool any_static = !m.static_box.empty();
  // Shadow culling: a shadow ray from p to the projector can be blocked by a body only if
  // p lies inside the body's silhouette seen from the projector and farther than the body.
  const Eigen::Matrix3f R_CW_f = R_WC_f.transpose();
  std::vector<Caster> moving_casters(moving_W.size());
  const std::vector<Caster>& static_casters = m.static_casters;
  if (m.p.cull) {
    Eigen::AlignedBox3d all_W;
    for (std::size_t k = 0; k < moving_W.size(); ++k) {
      moving_rect[k] = reachable(moving_W[k].min(), moving_W[k].max(), m.p.camera.X_WC, K, margin_px);
      moving_casters[k] = Caster::of(moving_W[k], R_WC, P_W);
      all_W.extend(moving_W[k]);
    }
    for (const Eigen::AlignedBox3d& box : m.static_box) all_W.extend(box);
    scene_rect = reachable(all_W.min(), all_W.max(), m.p.camera.X_WC, K, margin_px);
  }
  const PixelRect& chain_rect = moving_rect[0];
  // What to compute: `inner` gets the noise pass; the clean images reach kEdgeReach px
  // further, as far as the edge model looks, so that inner's pixels match a whole-frame
  // render.
  const PixelRect inner = extent.chain_only ? grown(chain_rect, extent.margin_px, W, H) : everything;
  const PixelRect cast_rect = extent.chain_only ? grown(inner, kEdgeReach, W, H) : everything;
  out.rendered = inner;

  auto t1 = std::chrono::steady_clock::now();
  // Rows dealt out in small chunks: the link covers a band of rows, so halves would not
  // balance. Each pixel's result depends on its index only, so any schedule is exact.
#pragma omp parallel for schedule(dynamic, 40) num_threads(threads)
  for (long pk = 0; pk < packets; ++pk) {
    const int v = static_cast<int>(pk / per_row);
    const int u0 = static_cast<int>(pk % per_row) * kPacket;
    if (!scene_rect.touches(u0, v) || !cast_rect.touches(u0, v))
      continue;  // the cleared images hold the misses
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;  // a packet is 16 neighbouring pixels
    alignas(64) RTCRayHit16 rh;
    alignas(64) int valid[kPacket];
    Eigen::Vector3f dirs[kPacket];
    for (int i = 0; i < kPacket; ++i) {
      const int u = u0 + i;
      valid[i] = cast_rect.contains(u, v) ? -1 : 0;
      dirs[i] = valid[i] ? direction(u, v, static_cast<std::size_t>(v) * W + u) : z_f;
      set_lane(rh, i, o_Wf, dirs[i], 0xFFFFFFFFu);  // Debian's Embree filters by mask
    }
    // The background first: its hits shorten the rays into the moving part. A ray keeps
    // the nearer of the two hits, as one cast of both scenes would.
    if (any_static) rtcIntersect16(valid, m.statics, &ctx, &rh);
    if (std::any_of(moving_rect.begin(), moving_rect.end(),
                    [&](const PixelRect& r) { return r.touches(u0, v); }))
      rtcIntersect16(valid, m.top, &ctx, &rh);
    alignas(64) RTCRay16 sr[2];  // shadow rays into the moving part and the background
    alignas(64) int svalid[2][kPacket] = {};
    bool any_shadow[2] = {false, false};
    for (int i = 0; i < kPacket; ++i) {
      if (!valid[i] || rh.hit.geomID[i] == RTC_INVALID_GEOMETRY_ID) continue;
      const std::size_t pix = static_cast<std::size_t>(v) * W + u0 + i;
      const unsigned inst = rh.hit.instID[0][i];
      const bool moving = inst != RTC_INVALID_GEOMETRY_ID;
      const unsigned geom = rh.hit.geomID[i];
      const float tz = rh.ray.tfar[i];
      // Embree reports instance hits' normals in the instance's own frame. Float math
      // with one square root per norm product: this block runs once per pixel.
      Eigen::Vector3f nrm(rh.hit.Ng_x[i], rh.hit.Ng_y[i], rh.hit.Ng_z[i]);
      if (moving) nrm = m.R_of[inst] * nrm;
      const float n2 = nrm.squaredNorm();
      const float nd = nrm.dot(dirs[i]);
      if (nd > 0) nrm = -nrm;  // face the camera
      const Eigen::Vector3f p_W = o_Wf + tz * dirs[i];
      const Eigen::Vector3f to_p = P_Wf - p_W;
      out.label[pix] = moving ? m.label_of[inst] : kLabelBackground;
      m.reflect[pix] = moving ? m.reflectance_of[inst] : m.static_reflectance[geom];
      out.depth_clean_m[pix] = tz;
      const float cos_c = std::min(std::abs(nd) / std::sqrt(n2 * dirs[i].squaredNorm()), 1.0F);
      m.cos_c[pix] = cos_c;
      out.incidence[pix] = static_cast<float>(acos_unit(cos_c));
      const float cos_p = nrm.dot(to_p) / std::sqrt(n2 * to_p.squaredNorm());
      m.cos_p[pix] = cos_p;
      if (!shadows) continue;
      if (!(cos_p > 0)) {
        m.lit[pix] = 0;  // the projector sees the surface from behind
        continue;
      }
      const Eigen::Vector3f org = p_W + (1e-5F / std::sqrt(n2)) * nrm;  // off the surface
      const Eigen::Vector3f sd = P_Wf - org;
      // Which scenes can block it: the moving part unless culled; the background unless
      // every background body is culled, or is the convex body the ray starts on.
      bool need[2] = {true, any_static};
      if (m.p.cull) {
        const Eigen::Vector3f q = R_CW_f * (p_W - P_Wf);  // p in the projector's frame
        need[0] = std::any_of(moving_casters.begin(), moving_casters.end(),
                              [&](const Caster& c) { return c.may_block(q); });
        need[1] = false;
        for (std::size_t k = 0; k < static_casters.size() && !need[1]; ++k)
          need[1] = !(!moving && k == geom && m.static_convex[k]) && static_casters[k].may_block(q);
      }
      for (int s = 0; s < 2; ++s) {
        if (!need[s]) continue;
        if (!any_shadow[s]) sr[s] = shadow_idle;
        svalid[s][i] = -1;
        any_shadow[s] = true;
        set_lane(sr[s], i, org, sd, 1.0F, 0xFFFFFFFFu);  // tfar 1: up to the projector
      }
    }
    for (int s = 0; s < 2; ++s) {
      if (!any_shadow[s]) continue;
      // Incoherent context: Embree 3.13.5's coherent occlusion path hung on these rays.
      RTCIntersectContext shadow_ctx;
      rtcInitIntersectContext(&shadow_ctx);
      rtcOccluded16(svalid[s], s == 0 ? m.top : m.statics, &shadow_ctx, &sr[s]);
      for (int i = 0; i < kPacket; ++i) {
        if (svalid[s][i] && sr[s].tfar[i] < 0.0F)  // -inf: blocked
          m.lit[static_cast<std::size_t>(v) * W + u0 + i] = 0;
      }
    }
  }
  m.times.cast = seconds_since(t1);

  // Occluded fractions: where an occluder was hit, what would be seen without it.
  t1 = std::chrono::steady_clock::now();
  out.visible_px.assign(m.count, 0);
  out.visible_px_unoccluded.assign(m.count, 0);
  out.occluded_fraction.assign(m.count, 0.0);
  if (!m.occluders.empty()) {
    m.label_no_occluders.assign(n, kLabelNothing);
#pragma omp parallel for schedule(dynamic, 40) num_threads(threads)
    for (long pk = 0; pk < packets; ++pk) {
      const int v = static_cast<int>(pk / per_row);
      const int u0 = static_cast<int>(pk % per_row) * kPacket;
      if (!chain_rect.touches(u0, v)) continue;  // no lane could be valid below
      alignas(64) RTCRayHit16 rh;
      alignas(64) int valid[kPacket];
      bool any = false;
      for (int i = 0; i < kPacket; ++i) {
        const int u = u0 + i;
        const std::size_t pix = static_cast<std::size_t>(v) * W + u;
        valid[i] = 0;
        const std::uint8_t l = u < W ? out.label[pix] : kLabelNothing;
        if (l >= kLabelOccluder0 && l < kLabelBackground) {
          // Outside chain_rect the chain cannot be behind the occluder.
          valid[i] = chain_rect.contains(u, v) ? -1 : 0;
          any = any || valid[i];
        }
      }
      if (!any) continue;
      for (int i = 0; i < kPacket; ++i) {
        const int u = u0 + i;
        // Inactive lanes get a finite ray too (see above).
        const Eigen::Vector3f d = valid[i] ? direction(u, v, static_cast<std::size_t>(v) * W + u)
                                           : z_f;  // the same jittered ray
        set_lane(rh, i, o_Wf, d, kMaskScene);
      }
      RTCIntersectContext ctx;
      rtcInitIntersectContext(&ctx);
      ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
      rtcIntersect16(valid, m.top, &ctx, &rh);
      if (any_static) rtcIntersect16(valid, m.statics, &ctx, &rh);  // the background may be nearer
      for (int i = 0; i < kPacket; ++i) {
        if (!valid[i] || rh.hit.geomID[i] == RTC_INVALID_GEOMETRY_ID) continue;
        const unsigned inst = rh.hit.instID[0][i];
        m.label_no_occluders[static_cast<std::size_t>(v) * W + u0 + i] =
            inst != RTC_INVALID_GEOMETRY_ID ? m.label_of[inst] : kLabelBackground;
      }
    }
  }
  // The chain is seen, with or without occluders, inside its rectangle only.
  const PixelRect counted = grown(chain_rect, 0, W, H);
  for (int v = counted.v0; v <= counted.v1; ++v)
    for (int u = counted.u0; u <= counted.u1; ++u) {
      const std::size_t pix = static_cast<std::size_t>(v) * W + u;
      const std::uint8_t l = out.label[pix];
      if (l < m.count) {
        ++out.visible_px[l];
        ++out.visible_px_unoccluded[l];
      } else if (!m.occluders.empty() && m.label_no_occluders[pix] < m.count) {
        ++out.visible_px_unoccluded[m.label_no_occluders[pix]];
      }
    }
  long vis = 0, unocc = 0;
  for (int c = 0; c < m.count; ++c) {
    vis += out.visible_px[c];
    unocc += out.visible_px_unoccluded[c];
    if (out.visible_px_unoccluded[c] > 0)
      out.occluded_fraction[c] =
          1.0 - static_cast<double>(out.visible_px[c]) / out.visible_px_unoccluded[c];
  }
  out.link_occluded_fraction = unocc > 0 ? 1.0 - static_cast<double>(vis) / unocc : 0.0;
  m.times.occlusion = seconds_since(t1);

  // Noise and artefacts, per pixel from the noise-free images.
  t1 = std::chrono::steady_clock::now();
  m.hole.assign(n, 0);
  if (noise.dropouts.enabled && noise.dropouts.hole_rate > 0) {
    std::uint64_t state = derive_seed(frame_seed, "holes");
    auto next = [&] { return unit_interval(splitmix64(state)); };
    // Poisson count: Knuth's product method, or a rounded normal for large rates.
    int holes = 0;
    const double rate = noise.dropouts.hole_rate;
    if (rate < 30) {
      const double limit = std::exp(-rate);
      for (double prod = next(); prod > limit; prod *= next()) ++holes;
    } else {
      const double u1 = 1.0 - next(), u2 = next();
      const double g = std::sqrt(-2 * std::log(u1)) * std::cos(2 * std::numbers::pi * u2);
      holes = std::max(0, static_cast<int>(std::lround(rate + std::sqrt(rate) * g)));
    }
    // Sizes log-normal: ln A ~ N(ln median, s^2) with s from the 90th percentile.
    const double mu = std::log(noise.dropouts.hole_median_px);
    const double s_ln = std::log(noise.dropouts.hole_p90_px / noise.dropouts.hole_median_px) /
                        1.2815515655446004;  // the standard normal's 90th percentile
    std::vector<int>& blob = m.blob;
    m.blob_stamp.resize(n, 0);  // pixel k is in the current blob when its stamp is blob_id
    for (int h = 0; h < holes; ++h) {
      const int u0 = std::min(W - 1, static_cast<int>(next() * W));
      const int v0 = std::min(H - 1, static_cast<int>(next() * H));
      const double g = inverse_normal_cdf(std::clamp(next(), 1e-12, 1 - 1e-12));
      const int area = static_cast<int>(std::clamp(std::lround(std::exp(mu + s_ln * g)), 1L,
                                                   static_cast<long>(Dropouts::kMaxHolePx)));
      // Grown one 4-neighbour of a random member at a time: a compact, ragged blob.
      if (++m.blob_id == 0) {  // the ids wrapped: forget every stamp
        std::fill(m.blob_stamp.begin(), m.blob_stamp.end(), 0U);
        m.blob_id = 1;
      }
      const std::uint32_t id = m.blob_id;
      blob.assign(1, v0 * W + u0);
      m.blob_stamp[static_cast<std::size_t>(blob[0])] = id;
      for (int tries = 0; static_cast<int>(blob.size()) < area && tries < 50 * area; ++tries) {
        const int k = blob[std::min(blob.size() - 1, static_cast<std::size_t>(next() * blob.size()))];
        const int d = std::min(3, static_cast<int>(next() * 4));
        const int u = k % W + (d == 0) - (d == 1), v = k / W + (d == 2) - (d == 3);
        if (u < 0 || u >= W || v < 0 || v >= H) continue;
        const std::size_t kk = static_cast<std::size_t>(v) * W + u;
        if (m.blob_stamp[kk] == id) continue;
        m.blob_stamp[kk] = id;
        blob.push_back(v * W + u);
      }
      for (const int k : blob) m.hole[static_cast<std::size_t>(k)] = 1;
    }
  }
  // Correlated axial noise: a white field over the box of hit pixels (plus the kernel's
  // reach), blurred row then column by a normalized Gaussian. Each white value depends on
  // its pixel's key only, so the field is the same for any thread count.
  const bool correlated = noise.axial.enabled && noise.axial.correlation_px > 0;
  int bu0 = W, bu1 = -1, bv0 = H, bv1 = -1;
  if (correlated) {  // hits lie in the cast rectangle
    for (int v = std::max(0, cast_rect.v0); v <= std::min(H - 1, cast_rect.v1); ++v)
      for (int u = std::max(0, cast_rect.u0); u <= std::min(W - 1, cast_rect.u1); ++u)
        if (out.depth_clean_m[static_cast<std::size_t>(v) * W + u] > 0) {
          bu0 = std::min(bu0, u), bu1 = std::max(bu1, u);
          bv0 = std::min(bv0, v), bv1 = std::max(bv1, v);
        }
  }
  if (correlated && bu1 >= 0) {
    const int R = static_cast<int>(m.blur_kernel.size() / 2);
    const int fu0 = std::max(0, bu0 - R), fu1 = std::min(W - 1, bu1 + R);
    const int fv0 = std::max(0, bv0 - R), fv1 = std::min(H - 1, bv1 + R);
    const int fw = fu1 - fu0 + 1, fh = fv1 - fv0 + 1;
    m.white.assign(static_cast<std::size_t>(fw) * fh, 0.0F);
    m.blurred.assign(static_cast<std::size_t>(fw) * fh, 0.0F);
    m.field.assign(n, 0.0F);
#pragma omp parallel for schedule(static) num_threads(threads)
    for (int v = fv0; v <= fv1; ++v)
      for (int u = fu0; u <= fu1; ++u)
        m.white[static_cast<std::size_t>(v - fv0) * fw + (u - fu0)] = static_cast<float>(
            normal(pixel_key(frame_seed, static_cast<std::size_t>(v) * W + u), kAxial));
    blur_rows(m.white, m.blurred, fw, fh, m.blur_kernel, threads);
    blur_columns(m.blurred, m.white, fw, fh, m.blur_kernel, threads);
    for (int y = 0; y < fh; ++y)
      std::copy_n(m.white.begin() + static_cast<std::ptrdiff_t>(y) * fw, fw,
                  m.field.begin() + static_cast<std::ptrdiff_t>(y + fv0) * W + fu0);
  }
  const double cos_max = std::cos(noise.dropouts.max_incidence);
  const double z_min = m.p.camera.z_min, z_max = m.p.camera.z_max;
  const double unit = K.depth_scale;
#pragma omp parallel for schedule(dynamic, 4) num_threads(threads)
  for (int v = inner.v0; v <= inner.v1; ++v) {
    for (int u = inner.u0; u <= inner.u1; ++u) {
      const std::size_t pix = static_cast<std::size_t>(v) * W + u;
      const double z0 = out.depth_clean_m[pix];
      if (z0 <= 0) continue;
      const std::uint64_t key = pixel_key(frame_seed, pix);
      if (noise.shadow.enabled && !m.lit[pix]) continue;
      if (noise.dropouts.enabled) {
        const double reflect = m.reflect[pix];
        if (m.cos_c[pix] < cos_max || m.cos_p[pix] < cos_max)
          continue;
        if (reflect * m.cos_p[pix] / (z0 * z0) < noise.dropouts.min_signal) continue;
        if (m.hole[pix]) continue;
      }
      double z = z0;
      if (noise.edges.enabled) {
        const EdgeEffects& e = noise.edges;
        bool near_edge = false;  // a farther neighbour (or one that sees nothing)
        bool far_1 = false, far_2 = false;  // a nearer pixel 1 or 2 px away
        double z_far = 0;        // the farthest neighbour across a jump, for flying pixels
        auto clean = [&](int uu, int vv) {
          return out.depth_clean_m[static_cast<std::size_t>(vv) * W + uu];
        };
        const int du[4] = {-1, 1, 0, 0}, dv[4] = {0, 0, -1, 1};
        for (int k = 0; k < 4; ++k) {
          const int uu = u + du[k], vv = v + dv[k];
          if (uu < 0 || uu >= W || vv < 0 || vv >= H) continue;
          const double zn = clean(uu, vv);
          if (zn <= 0 || zn - z0 > e.jump) {
            near_edge = true;
            z_far = std::max(z_far, zn);
          } else if (z0 - zn > e.jump) {
            far_1 = true;
          }
          // 2 px away: the jump must fall between the neighbour (on this pixel's surface)
          // and the pixel after it, not be the sum of two steps of a steep slope. Only
          // looked at when that band can drop anything (it costs a third of the pass).
          if (!(e.band_p2 > 0)) continue;
          const int u2 = u + kEdgeReach * du[k], v2 = v + kEdgeReach * dv[k];
          if (u2 < 0 || u2 >= W || v2 < 0 || v2 >= H) continue;
          const double z2 = clean(u2, v2);
          if (zn > 0 && std::abs(zn - z0) <= e.jump && z2 > 0 && zn - z2 > e.jump) far_2 = true;
        }
        // The far side first: its band is the camera's, whatever the near side does.
        if (far_1) {
          if (uniform(key, kEdge) < e.band_p1) continue;
        } else if (far_2) {
          if (uniform(key, kEdge) < e.band_p2) continue;
        } else if (near_edge) {
          if (uniform(key, kEdge) < e.p_drop) continue;
          if (z_far > 0 && uniform(key, kFlying) < e.p_flying) {
            const double lo = std::max(0.0, e.flying_position - e.flying_spread);
            const double hi = std::min(1.0, e.flying_position + e.flying_spread);
            z = z0 + (lo + uniform(key, kMix) * (hi - lo)) * (z_far - z0);  // between the two
          }
        }
      }
      if (noise.axial.enabled)
        z += noise.axial.sigma(z0, out.incidence[pix]) *
             (correlated ? static_cast<double>(m.field[pix]) : normal(key, kAxial));
      if (z < z_min || z > z_max) continue;
      const long q = static_cast<long>(z / unit + 0.5);  // z > 0 here
      if (q <= 0 || q > 65535) continue;
      out.depth.data[pix] = static_cast<std::uint16_t>(q);
      out.depth_m[pix] = static_cast<float>(noise.quantize ? q * unit : z);
    }
  }
  m.times.noise = seconds_since(t1);
}

}  // namespace linksight::sim
