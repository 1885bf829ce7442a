// Kernels of Algorithm 2 (Section V): kernel 1 associates points with nodes (Eq. 11);
// kernel 2 sums them per node for the mean (Eq. 12), either with the paper's global
// atomics or with per-work-group partial sums.
//
// Float arithmetic matches the CPU back ends operation for operation (no fused
// multiply-add, same order), so the associations are identical. Sums are 64-bit fixed
// point: integer addition is associative, so no work-group size or schedule changes
// the result.
#pragma OPENCL FP_CONTRACT OFF
#pragma OPENCL EXTENSION cl_khr_int64_base_atomics : enable

// 2^32 units per metre. Multiplying a float by a power of two is exact, so every
// coordinate with |v| >= 2^-9 m converts without rounding (smaller ones round at
// 2^-33 m). 1M points with |v| <= 1.5 m sum to at most 6.4e15 units, 1400 times
// below 2^63.
#define FIX_SCALE 4294967296.0f

inline long to_fixed(const float v) { return convert_long_rte(v * FIX_SCALE); }

// Kernel 1 (Eq. 11): nearest node by squared distance, ties to the lowest index.
kernel void associate(global const float* x, global const float* y, global const float* z,
                      const uint n, global const float* q, const int m, global int* assoc) {
  const size_t i = get_global_id(0);
  if (i >= n) return;
  const float px = x[i], py = y[i], pz = z[i];
  float best = INFINITY;
  int best_j = 0;
  for (int j = 0; j < m; ++j) {
    const float dx = px - q[3 * j], dy = py - q[3 * j + 1], dz = pz - q[3 * j + 2];
    const float d = dx * dx + dy * dy + dz * dz;
    if (d < best) {
      best = d;
      best_j = j;
    }
  }
  assoc[i] = best_j;
}

// Kernel 2, the paper's form: global atomic adds per point (acc: sum x, sum y, sum z, count per node).
kernel void accumulate_atomic(global const float* x, global const float* y,
                              global const float* z, global const int* assoc, const uint n,
                              global long* acc) {
  const size_t i = get_global_id(0);
  if (i >= n) return;
  const int j = assoc[i];
  atom_add(&acc[4 * j], to_fixed(x[i]));
  atom_add(&acc[4 * j + 1], to_fixed(y[i]));
  atom_add(&acc[4 * j + 2], to_fixed(z[i]));
  atom_add(&acc[4 * j + 3], 1L);
}

// Kernel 2, per-work-group partial sums: each group strides over the points and adds
// into local memory, then writes one row of partials.
kernel void accumulate_groups(global const float* x, global const float* y,
                              global const float* z, global const int* assoc, const uint n,
                              const int m, local long* lacc, global long* partial) {
  const int m4 = 4 * m;
  const int lid = (int)get_local_id(0), lsize = (int)get_local_size(0);
  for (int k = lid; k < m4; k += lsize) lacc[k] = 0;
  barrier(CLK_LOCAL_MEM_FENCE);
  for (size_t i = get_global_id(0); i < n; i += get_global_size(0)) {
    const int j = assoc[i];
    atom_add(&lacc[4 * j], to_fixed(x[i]));
    atom_add(&lacc[4 * j + 1], to_fixed(y[i]));
    atom_add(&lacc[4 * j + 2], to_fixed(z[i]));
    atom_add(&lacc[4 * j + 3], 1L);
  }
  barrier(CLK_LOCAL_MEM_FENCE);
  for (int k = lid; k < m4; k += lsize) partial[get_group_id(0) * m4 + k] = lacc[k];
}

// Sums the groups' partials, one work item per value.
kernel void sum_partials(global const long* partial, const uint groups, const int m4,
                         global long* acc) {
  const int k = (int)get_global_id(0);
  if (k >= m4) return;
  long s = 0;
  for (uint g = 0; g < groups; ++g) s += partial[g * m4 + k];
  acc[k] = s;
}
