// chain-fit's pass over the points (issue 17, part 7; tracker/src/chain_fit.cpp is the
// reference): kernel chain_point finds each point's component surface (or reuses the
// recorded one) and its residual, weight and Jacobian row; kernel chain_sums sums them in
// the CPU's blocks, each block in point order, one work item per block and component.
// The search in float (chain_search.hpp: every component's float distance, the argmin,
// ties to the lower index; the CPU skips components that cannot win, which gives the same
// answer), the rest in double: the CPU's operations in the CPU's order and no contraction,
// so every value, association and sum is the CPU's bits (OpenCL's double sqrt and division
// are correctly rounded, and its float sqrt under -cl-fp32-correctly-rounded-divide-sqrt,
// which the build passes, as IEEE 754 asks of the CPU's).
#pragma OPENCL FP_CONTRACT OFF
#pragma OPENCL EXTENSION cl_khr_fp64 : enable

// The chain's frames, `count` of each, packed one array after another in `fr`.
#define CX(k) fr[(k)]
#define CY(k) fr[count + (k)]
#define CZ(k) fr[2 * count + (k)]
#define AX(k) fr[3 * count + (k)]
#define AY(k) fr[4 * count + (k)]
#define AZ(k) fr[5 * count + (k)]
#define T1X(k) fr[6 * count + (k)]
#define T1Y(k) fr[7 * count + (k)]
#define T1Z(k) fr[8 * count + (k)]
#define T2X(k) fr[9 * count + (k)]
#define T2Y(k) fr[10 * count + (k)]
#define T2Z(k) fr[11 * count + (k)]

// VALS, the values per point in `val` (robust cost, residual, weight, then the Jacobian
// row), comes from the build options (chain_pass.hpp's kChainValues).

typedef struct {
  double distance, s, norm;
  int neck;
} Candidate;

// The ball of radius r at the centre and the capsule of radius rn along [0, L] of the
// axis: the nearer, from d = p - c (dn2 = |d|^2).
Candidate candidate(const double dx, const double dy, const double dz, const double dn2,
                    const double ax, const double ay, const double az, const double r,
                    const double rn, const double L) {
  Candidate out;
  const double dn = sqrt(dn2);
  out.distance = dn - r;
  out.s = 0.0;
  out.neck = 0;
  out.norm = dn;
  const double t = dx * ax + dy * ay + dz * az;
  const double s = t < 0.0 ? 0.0 : (L < t ? L : t);  // std::clamp(t, 0, L)
  const double ex = dx - s * ax, ey = dy - s * ay, ez = dz - s * az;
  const double en = sqrt(ex * ex + ey * ey + ez * ez);
  const double neck = en - rn;
  if (neck < out.distance) {
    out.distance = neck;
    out.s = s;
    out.neck = 1;
    out.norm = en;
  }
  return out;
}

// Component k's float distance to p, as chain_search.hpp's distance() computes each lane:
// the centre and axis rounded to float, the nearer of ball and neck.
inline float distance_f(global const double* fr, const int count, const int k, const float px,
                        const float py, const float pz, const float r, const float rn,
                        const float L) {
  const float dx = px - (float)CX(k), dy = py - (float)CY(k), dz = pz - (float)CZ(k);
  const float ax = (float)AX(k), ay = (float)AY(k), az = (float)AZ(k);
  const float ball = sqrt(dx * dx + dy * dy + dz * dz) - r;
  const float t = dx * ax + dy * ay + dz * az;
  const float lo = t < 0.0f ? 0.0f : t;
  const float s = L < lo ? L : lo;  // std::clamp(t, 0, L)
  const float ex = dx - s * ax, ey = dy - s * ay, ez = dz - s * az;
  const float neck = sqrt(ex * ex + ey * ey + ez * ez) - rn;
  return neck < ball ? neck : ball;
}

inline Candidate try_k(global const double* fr, const int count, const int k, const double px,
                       const double py, const double pz, const double r, const double rn,
                       const double L) {
  const double dx = px - CX(k), dy = py - CY(k), dz = pz - CZ(k);
  return candidate(dx, dy, dz, dx * dx + dy * dy + dz * dz, AX(k), AY(k), AZ(k), r, rn, L);
}

// Eigen's unitOrthogonal of a 3-vector (a point exactly on an axis or a centre).
void unit_orthogonal(const double x, const double y, const double z, double* o) {
  const double eps = 1e-12;  // NumTraits<double>::dummy_precision()
  if (!(fabs(x) <= fabs(z) * eps) || !(fabs(y) <= fabs(z) * eps)) {
    const double inv = 1.0 / sqrt(x * x + y * y);
    o[0] = -y * inv;
    o[1] = x * inv;
    o[2] = 0.0;
  } else {
    const double inv = 1.0 / sqrt(z * z + y * y);
    o[0] = 0.0;
    o[1] = -z * inv;
    o[2] = y * inv;
  }
}

inline double huber(const double v, const double h) {
  const double a = fabs(v);
  return a <= h ? 0.5 * v * v : h * (a - 0.5 * h);
}

// geo: ball radius, neck radius, neck length, Huber threshold, max distance.
kernel void chain_point(global const float* x, global const float* y, global const float* z,
                        const uint n, global const double* fr, const int count,
                        global const double* geo, const int search,
                        global const short* assoc_in, global short* assoc_out,
                        global int* comp, global double* val, const uint block,
                        const uint stride) {
  const size_t i = get_global_id(0);
  if (i >= n) return;
  // A coarse pass (stride > 1) takes every stride-th point of each block: the others add
  // nothing (a zero cost, no component), as the CPU skips them.
  if ((i % block) % stride != 0) {
    val[VALS * i] = 0.0;
    comp[i] = -1;
    return;
  }
  const double r = geo[0], rn = geo[1], L = geo[2], h = geo[3], maxd = geo[4];
  const double px = (double)x[i], py = (double)y[i], pz = (double)z[i];
  int bk = -1;
  Candidate best;
  if (search) {
    const float rf = (float)r, rnf = (float)rn, Lf = (float)L;
    float bestf = INFINITY;
    bk = 0;
    for (int k = 0; k < count; ++k) {
      const float d = distance_f(fr, count, k, x[i], y[i], z[i], rf, rnf, Lf);
      if (d < bestf) {
        bestf = d;
        bk = k;
      }
    }
    assoc_out[i] = (short)bk;
  } else {
    bk = assoc_in[i];
  }
  best = try_k(fr, count, bk, px, py, pz, r, rn, L);
  const double res = best.distance;
  global double* v = val + VALS * i;
  v[0] = huber(fmin(fabs(res), maxd), h);
  if (fabs(res) > maxd) {
    comp[i] = -1;
    return;
  }
  // The outward normal at the nearest point, as hit_of.
  const double ax = AX(bk), ay = AY(bk), az = AZ(bk);
  const double dx = px - CX(bk), dy = py - CY(bk), dz = pz - CZ(bk);
  double e[3];
  if (best.neck) {
    e[0] = dx - best.s * ax;
    e[1] = dy - best.s * ay;
    e[2] = dz - best.s * az;
  } else {
    e[0] = dx;
    e[1] = dy;
    e[2] = dz;
  }
  double nrm[3];
  if (best.norm > 0) {
    nrm[0] = e[0] / best.norm;
    nrm[1] = e[1] / best.norm;
    nrm[2] = e[2] / best.norm;
  } else if (best.neck) {
    unit_orthogonal(ax, ay, az, nrm);
  } else {
    nrm[0] = ax;
    nrm[1] = ay;
    nrm[2] = az;
  }
  const double lever = best.neck ? best.s : 0.0;
  const double dot1 = nrm[0] * T1X(bk) + nrm[1] * T1Y(bk) + nrm[2] * T1Z(bk);
  const double dot2 = nrm[0] * T2X(bk) + nrm[1] * T2Y(bk) + nrm[2] * T2Z(bk);
  comp[i] = bk;
  v[1] = res;
  v[2] = fabs(res) <= h ? 1.0 : h / fabs(res);
  v[3] = -nrm[0];
  v[4] = -nrm[1];
  v[5] = -nrm[2];
  v[6] = -lever * dot1;
  v[7] = -lever * dot2;
}

// One work item per (block, k): k < count sums component k's normal equations (the 15
// lower entries of H column by column, then b) and point count over the block's points in
// order; k == count sums the block's robust cost, its inliers' squared residuals and their
// count. out_d: 20 doubles per (block, k); out_l: one count.
kernel void chain_sums(global const int* comp, global const double* val, const uint n,
                       const int count, const uint block, const uint blocks,
                       global double* out_d, global long* out_l) {
  const size_t id = get_global_id(0);
  if (id >= (size_t)blocks * (size_t)(count + 1)) return;
  const uint blk = (uint)(id / (size_t)(count + 1));
  const int k = (int)(id % (size_t)(count + 1));
  const uint begin = blk * block;
  const uint end = min(n, begin + block);
  global double* o = out_d + 20 * id;
  if (k == count) {
    double robust = 0.0, sum2 = 0.0;
    long inliers = 0;
    for (uint i = begin; i < end; ++i) {
      robust += val[VALS * i];
      if (comp[i] < 0) continue;
      const double res = val[VALS * i + 1];
      sum2 += res * res;
      ++inliers;
    }
    for (int j = 0; j < 20; ++j) o[j] = 0.0;
    o[0] = robust;
    o[1] = sum2;
    out_l[id] = inliers;
    return;
  }
  double H[15], b[5];
  for (int j = 0; j < 15; ++j) H[j] = 0.0;
  for (int j = 0; j < 5; ++j) b[j] = 0.0;
  long c_k = 0;
  for (uint i = begin; i < end; ++i) {
    if (comp[i] != k) continue;
    global const double* v = val + VALS * i;
    const double res = v[1], w = v[2];
    double J[5];
    for (int j = 0; j < 5; ++j) J[j] = v[3 + j];
    ++c_k;
    int e = 0;
    for (int c = 0; c < 5; ++c)
      for (int r2 = c; r2 < 5; ++r2) H[e++] += w * J[r2] * J[c];
    const double wr = w * res;
    for (int c = 0; c < 5; ++c) b[c] -= wr * J[c];
  }
  for (int j = 0; j < 15; ++j) o[j] = H[j];
  for (int j = 0; j < 5; ++j) o[15 + j] = b[j];
  out_l[id] = c_k;
}
