// The sensor's casting stages (see Sensor::render in sensor.cpp for their order): the
// scene update, the culling plan, the cast with projector shadows, and the occlusion
// truth. Each pixel's result depends on its index only, so any schedule is exact.
#include <omp.h>

#include <algorithm>

#include "sensor_impl.hpp"

namespace linksight::sim {

using detail::kMaskScene;
using detail::set_lane;

std::vector<Eigen::AlignedBox3d> Sensor::Impl::update_scene(const std::vector<Eigen::Isometry3d>& X_WK,
                                                             double t) {
  for (int c = 0; c < count; ++c) {
    detail::set_transform(chain[c], X_WK[c]);
    rtcCommitGeometry(chain[c]);
    R_of[chain_id[c]] = X_WK[c].linear().cast<float>();
  }
  std::vector<Eigen::AlignedBox3d> moving_W;  // world bounds: the chain, then each occluder
  moving_W.emplace_back();
  for (int c = 0; c < count; ++c)
    for (int k = 0; k < 8; ++k)
      moving_W[0].extend(X_WK[c] * component_box.corner(static_cast<Eigen::AlignedBox3d::CornerType>(k)));
  for (std::size_t k = 0; k < occluders.size(); ++k) {
    moving_W.emplace_back();  // empty while absent: no rectangle, never casts a shadow
    if (!occluders[k].present(t)) {
      if (occluder_on[k]) rtcDisableGeometry(occluding[k]);
      occluder_on[k] = false;
      continue;
    }
    if (!occluder_on[k]) rtcEnableGeometry(occluding[k]);
    occluder_on[k] = true;
    const Eigen::Isometry3d X_WO = occluders[k].path.pose(t);
    for (int c = 0; c < 8; ++c)
      moving_W.back().extend(X_WO * occluder_box[k].corner(static_cast<Eigen::AlignedBox3d::CornerType>(c)));
    detail::set_transform(occluding[k], X_WO);
    rtcCommitGeometry(occluding[k]);
    R_of[occluder_id[k]] = X_WO.linear().cast<float>();
  }
  rtcCommitScene(top);
  check("scene update");
  return moving_W;
}

FramePlan Sensor::Impl::plan(std::vector<Eigen::AlignedBox3d> moving_W, const RenderExtent& extent,
                             std::uint64_t frame_seed) const {
  const io::Intrinsics& K = p.camera.intrinsics;
  const NoiseParams& np = p.noise;
  const int W = K.width, H = K.height;
  FramePlan f;
  f.frame_seed = frame_seed;
  f.threads = p.threads > 0 ? p.threads : omp_get_max_threads();
  f.rays.K = &K;
  f.rays.R_WC_f = p.camera.X_WC.linear().cast<float>();
  f.rays.jitter = np.lateral.enabled && np.lateral.sigma_px > 0;
  f.rays.pinhole = K.model == io::Distortion::none;
  f.rays.sigma_px = np.lateral.sigma_px;
  f.rays.inv_fx = 1.0 / K.fx;
  f.rays.inv_fy = 1.0 / K.fy;
  f.rays.frame_seed = frame_seed;
  f.o_Wf = p.camera.X_WC.translation().cast<float>();
  f.per_row = (W + kRayPacket - 1) / kRayPacket;
  f.packets = static_cast<long>(f.per_row) * H;
  const double margin_px = 1.0 + (f.rays.jitter ? f.rays.sigma_px * detail::kMaxNormal32 : 0.0);
  const PixelRect everything{{0, W - 1, 0, H - 1}};
  f.scene_rect = everything;
  f.moving_rect.assign(moving_W.size(), everything);
  f.moving_casters.resize(moving_W.size());
  if (p.cull) {
    const Eigen::Vector3d P_W = p.camera.X_WC * Eigen::Vector3d(np.shadow.baseline, 0, 0);
    Eigen::AlignedBox3d all_W;
    for (std::size_t k = 0; k < moving_W.size(); ++k) {
      f.moving_rect[k] = reachable(moving_W[k].min(), moving_W[k].max(), p.camera.X_WC, K, margin_px);
      f.moving_casters[k] = ShadowCaster::of(moving_W[k], p.camera.X_WC.linear(), P_W);
      all_W.extend(moving_W[k]);
    }
    for (const Eigen::AlignedBox3d& box : static_box) all_W.extend(box);
    f.scene_rect = reachable(all_W.min(), all_W.max(), p.camera.X_WC, K, margin_px);
  }
  f.chain_rect = f.moving_rect[0];
  f.inner = extent.chain_only ? grown(f.chain_rect, extent.margin_px, W, H) : everything;
  f.cast_rect = extent.chain_only ? grown(f.inner, kEdgeReachPx, W, H) : everything;
  f.moving_W = std::move(moving_W);
  return f;
}

void Sensor::Impl::cast(const FramePlan& f, DepthFrame& out) {
  const io::Intrinsics& K = p.camera.intrinsics;
  const int W = K.width;
  const int per_row = f.per_row;
  const long packets = f.packets;
  const std::size_t n = static_cast<std::size_t>(W) * K.height;
  // Read at hit pixels only, which the cast writes; lit defaults to 1 (only shadows clear it).
  cos_c.resize(n);
  cos_p.resize(n);
  reflect.resize(n);
  lit.assign(n, 1);
  const bool shadows = p.noise.shadow.enabled;
  const bool any_static = !static_box.empty();
  const detail::RayDirections& direction = f.rays;
  const Eigen::Vector3f& o_Wf = f.o_Wf;
  const Eigen::Vector3f z_f = Eigen::Vector3f::UnitZ();
  const Eigen::Vector3f P_Wf =
      (p.camera.X_WC * Eigen::Vector3d(p.noise.shadow.baseline, 0, 0)).cast<float>();
  const Eigen::Matrix3f R_CW_f = direction.R_WC_f.transpose();
  // Inactive shadow lanes still hold a finite ray: Embree's packet path reads them too.
  alignas(64) RTCRay16 shadow_idle;
  for (int i = 0; i < kRayPacket; ++i)
    set_lane(shadow_idle, i, o_Wf, z_f, 0.0F, 0xFFFFFFFFu);
  // Rows dealt out in small chunks: the link covers a band of rows, so halves would not
  // balance.
#pragma omp parallel for schedule(dynamic, 40) num_threads(f.threads)
  for (long pk = 0; pk < packets; ++pk) {
    const int v = static_cast<int>(pk / per_row);
    const int u0 = static_cast<int>(pk % per_row) * kRayPacket;
    if (!f.scene_rect.touches(u0, v) || !f.cast_rect.touches(u0, v))
      continue;  // the cleared images hold the misses
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;  // a packet is 16 neighbouring pixels
    alignas(64) RTCRayHit16 rh;
    alignas(64) int valid[kRayPacket];
    Eigen::Vector3f dirs[kRayPacket];
    for (int i = 0; i < kRayPacket; ++i) {
      const int u = u0 + i;
      valid[i] = f.cast_rect.contains(u, v) ? -1 : 0;
      dirs[i] = valid[i] ? direction(u, v, static_cast<std::size_t>(v) * W + u) : z_f;
      set_lane(rh, i, o_Wf, dirs[i], 0xFFFFFFFFu);  // Debian's Embree filters by mask
    }
    // The background first: its hits shorten the rays into the moving part. A ray keeps
    // the nearer of the two hits, as one cast of both scenes would.
    if (any_static) rtcIntersect16(valid, statics, &ctx, &rh);
    if (std::any_of(f.moving_rect.begin(), f.moving_rect.end(),
                    [&](const PixelRect& r) { return r.touches(u0, v); }))
      rtcIntersect16(valid, top, &ctx, &rh);
    alignas(64) RTCRay16 sr[2];  // shadow rays into the moving part and the background
    alignas(64) int svalid[2][kRayPacket] = {};
    bool any_shadow[2] = {false, false};
    for (int i = 0; i < kRayPacket; ++i) {
      if (!valid[i] || rh.hit.geomID[i] == RTC_INVALID_GEOMETRY_ID) continue;
      const std::size_t pix = static_cast<std::size_t>(v) * W + u0 + i;
      const unsigned inst = rh.hit.instID[0][i];
      const bool moving = inst != RTC_INVALID_GEOMETRY_ID;
      const unsigned geom = rh.hit.geomID[i];
      const float tz = rh.ray.tfar[i];
      // Embree reports instance hits' normals in the instance's own frame. Float math
      // with one square root per norm product: this block runs once per pixel.
      Eigen::Vector3f nrm(rh.hit.Ng_x[i], rh.hit.Ng_y[i], rh.hit.Ng_z[i]);
      if (moving) nrm = R_of[inst] * nrm;
      const float n2 = nrm.squaredNorm();
      const float nd = nrm.dot(dirs[i]);
      if (nd > 0) nrm = -nrm;  // face the camera
      const Eigen::Vector3f p_W = o_Wf + tz * dirs[i];
      const Eigen::Vector3f to_p = P_Wf - p_W;
      out.label[pix] = moving ? label_of[inst] : kLabelBackground;
      reflect[pix] = moving ? reflectance_of[inst] : static_reflectance[geom];
      out.depth_clean_m[pix] = tz;
      const float cos_cam = std::min(std::abs(nd) / std::sqrt(n2 * dirs[i].squaredNorm()), 1.0F);
      cos_c[pix] = cos_cam;
      out.incidence[pix] = static_cast<float>(detail::acos_unit(cos_cam));
      const float cos_proj = nrm.dot(to_p) / std::sqrt(n2 * to_p.squaredNorm());
      cos_p[pix] = cos_proj;
      if (!shadows) continue;
      if (!(cos_proj > 0)) {
        lit[pix] = 0;  // the projector sees the surface from behind
        continue;
      }
      const Eigen::Vector3f org = p_W + (1e-5F / std::sqrt(n2)) * nrm;  // off the surface
      const Eigen::Vector3f sd = P_Wf - org;
      // Which scenes can block it: the moving part unless culled; the background unless
      // every background body is culled, or is the convex body the ray starts on.
      bool need[2] = {true, any_static};
      if (p.cull) {
        const Eigen::Vector3f q = R_CW_f * (p_W - P_Wf);  // p in the projector's frame
        // Loops, not std::any_of: GCC left that call's lambda out of line (callgrind).
        need[0] = false;
        for (std::size_t k = 0; k < f.moving_casters.size() && !need[0]; ++k)
          need[0] = f.moving_casters[k].may_block(q);
        need[1] = false;
        for (std::size_t k = 0; k < static_casters.size() && !need[1]; ++k)
          need[1] = !(!moving && k == geom && static_convex[k]) && static_casters[k].may_block(q);
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
      rtcOccluded16(svalid[s], s == 0 ? top : statics, &shadow_ctx, &sr[s]);
      for (int i = 0; i < kRayPacket; ++i) {
        if (svalid[s][i] && sr[s].tfar[i] < 0.0F)  // -inf: blocked
          lit[static_cast<std::size_t>(v) * W + u0 + i] = 0;
      }
    }
  }
}

void Sensor::Impl::occlusion_truth(const FramePlan& f, DepthFrame& out) {
  // Where an occluder was hit, what would be seen without it.
  const io::Intrinsics& K = p.camera.intrinsics;
  const int W = K.width, H = K.height;
  const int per_row = f.per_row;
  const long packets = f.packets;
  const std::size_t n = static_cast<std::size_t>(W) * H;
  const bool any_static = !static_box.empty();
  const detail::RayDirections& direction = f.rays;
  const Eigen::Vector3f& o_Wf = f.o_Wf;
  const Eigen::Vector3f z_f = Eigen::Vector3f::UnitZ();
  out.visible_px.assign(count, 0);
  out.visible_px_unoccluded.assign(count, 0);
  out.occluded_fraction.assign(count, 0.0);
  if (!occluders.empty()) {
    label_no_occluders.assign(n, kLabelNothing);
#pragma omp parallel for schedule(dynamic, 40) num_threads(f.threads)
    for (long pk = 0; pk < packets; ++pk) {
      const int v = static_cast<int>(pk / per_row);
      const int u0 = static_cast<int>(pk % per_row) * kRayPacket;
      if (!f.chain_rect.touches(u0, v)) continue;  // no lane could be valid below
      alignas(64) RTCRayHit16 rh;
      alignas(64) int valid[kRayPacket];
      bool any = false;
      for (int i = 0; i < kRayPacket; ++i) {
        const int u = u0 + i;
        const std::size_t pix = static_cast<std::size_t>(v) * W + u;
        valid[i] = 0;
        const std::uint8_t l = u < W ? out.label[pix] : kLabelNothing;
        if (l >= kLabelOccluder0 && l < kLabelBackground) {
          // Outside chain_rect the chain cannot be behind the occluder.
          valid[i] = f.chain_rect.contains(u, v) ? -1 : 0;
          any = any || valid[i];
        }
      }
      if (!any) continue;
      for (int i = 0; i < kRayPacket; ++i) {
        const int u = u0 + i;
        // Inactive lanes get a finite ray too (see above).
        const Eigen::Vector3f d = valid[i] ? direction(u, v, static_cast<std::size_t>(v) * W + u)
                                           : z_f;  // the same jittered ray
        set_lane(rh, i, o_Wf, d, kMaskScene);
      }
      RTCIntersectContext ctx;
      rtcInitIntersectContext(&ctx);
      ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
      rtcIntersect16(valid, top, &ctx, &rh);
      if (any_static) rtcIntersect16(valid, statics, &ctx, &rh);  // the background may be nearer
      for (int i = 0; i < kRayPacket; ++i) {
        if (!valid[i] || rh.hit.geomID[i] == RTC_INVALID_GEOMETRY_ID) continue;
        const unsigned inst = rh.hit.instID[0][i];
        label_no_occluders[static_cast<std::size_t>(v) * W + u0 + i] =
            inst != RTC_INVALID_GEOMETRY_ID ? label_of[inst] : kLabelBackground;
      }
    }
  }
  // The chain is seen, with or without occluders, inside its rectangle only.
  const PixelRect counted = grown(f.chain_rect, 0, W, H);
  for (int v = counted.v0; v <= counted.v1; ++v)
    for (int u = counted.u0; u <= counted.u1; ++u) {
      const std::size_t pix = static_cast<std::size_t>(v) * W + u;
      const std::uint8_t l = out.label[pix];
      if (l < count) {
        ++out.visible_px[l];
        ++out.visible_px_unoccluded[l];
      } else if (!occluders.empty() && label_no_occluders[pix] < count) {
        ++out.visible_px_unoccluded[label_no_occluders[pix]];
      }
    }
  long vis = 0, unocc = 0;
  for (int c = 0; c < count; ++c) {
    vis += out.visible_px[c];
    unocc += out.visible_px_unoccluded[c];
    if (out.visible_px_unoccluded[c] > 0)
      out.occluded_fraction[c] =
          1.0 - static_cast<double>(out.visible_px[c]) / out.visible_px_unoccluded[c];
  }
  out.link_occluded_fraction = unocc > 0 ? 1.0 - static_cast<double>(vis) / unocc : 0.0;
}

NoiseInput Sensor::Impl::noise_input(const DepthFrame& out) const {
  return {out.width, out.height, out.depth_clean_m, out.incidence, cos_c, cos_p, reflect, lit};
}

}  // namespace linksight::sim
