#include "linksight/sim/sensor.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "sensor_impl.hpp"

namespace linksight::sim {
namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// A W x H frame with nothing rendered yet: the images the stages fill, cleared.
void clear(DepthFrame& out, const io::Intrinsics& K) {
  const int W = K.width, H = K.height;
  const std::size_t n = static_cast<std::size_t>(W) * H;
  out.width = W;
  out.height = H;
  out.depth_clean_m.assign(n, 0.0F);
  out.label.assign(n, kLabelNothing);
  out.incidence.assign(n, std::numeric_limits<float>::quiet_NaN());
}

}  // namespace

std::string_view to_string(Shape::Kind kind) {
  switch (kind) {
    case Shape::Kind::box:
      return "box";
    case Shape::Kind::cylinder:
      return "cylinder";
    case Shape::Kind::sphere:
      return "sphere";
    case Shape::Kind::mesh:
      return "mesh";
  }
  return "unknown";
}

Shape::Kind parse_shape_kind(std::string_view name) {
  for (Shape::Kind k : {Shape::Kind::box, Shape::Kind::cylinder, Shape::Kind::sphere, Shape::Kind::mesh})
    if (name == to_string(k)) return k;
  throw std::invalid_argument("unknown shape '" + std::string(name) +
                              "' (expected box, cylinder, sphere or mesh)");
}

void Shape::validate() const {
  fields::check(*this, "shape");
  if (!(half_extents.minCoeff() > 0))
    fields::fail("shape", "half_extents_m", half_extents.minCoeff(), "must all be > 0");
  if (kind == Kind::mesh && mesh.empty() && (!mesh_data || mesh_data->triangles.empty()))
    throw fields::FieldError("mesh", "(none)", "a mesh shape needs a mesh file", "shape");
}

void Occluder::validate() const {
  shape.validate();
  fields::check(*this, "occluder");
  // An absent bound is open (-inf, +inf); a given one is a time in the episode, and an
  // end at 0 would be an occluder that never appears.
  if (from_s != -std::numeric_limits<double>::infinity() && !fields::obeys(fields::in(0, 1e6), from_s))
    fields::fail("occluder", "from_s", from_s, fields::describe(fields::in(0, 1e6)));
  if (to_s != std::numeric_limits<double>::infinity() &&
      !fields::obeys(fields::in_lo_open(0, 1e6), to_s))
    fields::fail("occluder", "to_s", to_s, fields::describe(fields::in_lo_open(0, 1e6)));
  if (!(to_s > from_s))
    fields::fail("occluder", "to_s", to_s, "must be > from_s (" + format_shortest(from_s) + ")");
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
      TriangleMesh m = mesh_data ? *mesh_data : load_mesh(mesh);  // names a bad file
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
  m.noise.emplace(params.noise, params.camera);
  // Meshes first: a missing file fails before Embree is set up.
  const TriangleMesh component = component_mesh(geometry, params.component_segments);
  std::vector<TriangleMesh> occluder_meshes, background_meshes;
  for (std::size_t k = 0; k < m.occluders.size(); ++k) {
    try {
      m.occluders[k].validate();
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
    m.chain.push_back(m.instance(comp, Eigen::Isometry3d::Identity(), detail::kMaskScene,
                                 static_cast<std::uint8_t>(c), params.chain_reflectance, m.chain_id));
  }
  for (std::size_t k = 0; k < m.occluders.size(); ++k) {
    Eigen::AlignedBox3d box;
    for (const Eigen::Vector3f& v : occluder_meshes[k].vertices) box.extend(v.cast<double>());
    m.occluder_box.push_back(box);
    m.occluding.push_back(m.instance(m.mesh_scene(occluder_meshes[k]),
                                     m.occluders[k].path.pose(0.0), detail::kMaskOccluder,
                                     static_cast<std::uint8_t>(kLabelOccluder0 + k),
                                     m.occluders[k].reflectance, m.occluder_id));
    m.occluder_on.push_back(true);
  }
  m.statics = rtcNewScene(m.device);
  rtcSetSceneFlags(m.statics, RTC_SCENE_FLAG_ROBUST);
  for (std::size_t k = 0; k < background.size(); ++k) {
    const Eigen::Isometry3f X_WO = background[k].X_WO.cast<float>();
    const unsigned id = m.attach_mesh(m.statics, background_meshes[k], X_WO, detail::kMaskScene);
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
    m.static_casters.push_back(ShadowCaster::of(box, params.camera.X_WC.linear(), P_W));
  rtcCommitScene(m.top);
  rtcCommitScene(m.statics);
  m.check("scene");
}

Sensor::~Sensor() = default;

const SensorParams& Sensor::params() const { return impl_->p; }
const SensorTimes& Sensor::last_times() const { return impl_->times; }
NoiseInput Sensor::last_noise_input(const DepthFrame& frame) const { return impl_->noise_input(frame); }

DepthFrame Sensor::render(const std::vector<Eigen::Isometry3d>& X_WK, double t,
                          std::uint64_t seed, std::uint64_t frame,
                          const RenderExtent& extent) {
  DepthFrame out;
  render(X_WK, t, seed, frame, out, extent);
  return out;
}

// The stages, each timed: the scene moved to time t, the culling plan, the cast with
// projector shadows (noise-free depth, labels, incidence), the occlusion truth, and the
// noise model on the noise-free images.
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
  auto t0 = std::chrono::steady_clock::now();
  std::vector<Eigen::AlignedBox3d> moving_W = m.update_scene(X_WK, t);
  m.times.scene = seconds_since(t0);

  clear(out, m.p.camera.intrinsics);
  const FramePlan plan = m.plan(std::move(moving_W), extent, detail::sensor_frame_seed(seed, frame));
  out.rendered = plan.inner;
  t0 = std::chrono::steady_clock::now();
  m.cast(plan, out);
  m.times.cast = seconds_since(t0);

  t0 = std::chrono::steady_clock::now();
  m.occlusion_truth(plan, out);
  m.times.occlusion = seconds_since(t0);

  t0 = std::chrono::steady_clock::now();
  m.noise->apply(m.noise_input(out), seed, frame, plan.inner, plan.cast_rect, plan.threads,
                 out.depth, out.depth_m);
  m.times.noise = seconds_since(t0);
}

}  // namespace linksight::sim
