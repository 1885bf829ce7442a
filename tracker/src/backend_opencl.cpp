// OpenCL back end (Section V, Algorithm 2). Context, queue and program are made once
// per back end; buffers only grow; the points go up once per frame; each iteration
// sends the nodes (36 floats for 12) and reads back the per-node sums and counts (the
// re-initialization check of Algorithm 2 needs them on the host).
#define CL_TARGET_OPENCL_VERSION 120
#include <CL/cl.h>

#include <algorithm>
#include <cctype>
#include <cstring>
#include <stdexcept>
#include <string>
#include <utility>

#include "linksight/tracker/backend.hpp"
#include "linksight/tracker/opencl.hpp"
#include "chain_pass.hpp"

namespace linksight {
namespace detail {
extern const char kSomKernelSource[];
extern const char kChainKernelSource[];
}  // namespace detail

namespace {

constexpr std::size_t kMaxGroups = 1024;  // partial-sum rows of the reduction

const char* error_name(cl_int e) {
  switch (e) {
    case CL_DEVICE_NOT_FOUND:
      return "CL_DEVICE_NOT_FOUND";
    case CL_OUT_OF_RESOURCES:
      return "CL_OUT_OF_RESOURCES";
    case CL_OUT_OF_HOST_MEMORY:
      return "CL_OUT_OF_HOST_MEMORY";
    case CL_MEM_OBJECT_ALLOCATION_FAILURE:
      return "CL_MEM_OBJECT_ALLOCATION_FAILURE";
    case CL_BUILD_PROGRAM_FAILURE:
      return "CL_BUILD_PROGRAM_FAILURE";
    case CL_INVALID_VALUE:
      return "CL_INVALID_VALUE";
    case CL_INVALID_KERNEL_ARGS:
      return "CL_INVALID_KERNEL_ARGS";
    case CL_INVALID_WORK_GROUP_SIZE:
      return "CL_INVALID_WORK_GROUP_SIZE";
    case CL_INVALID_BUFFER_SIZE:
      return "CL_INVALID_BUFFER_SIZE";
    case CL_INVALID_GLOBAL_WORK_SIZE:
      return "CL_INVALID_GLOBAL_WORK_SIZE";
    case -1001:
      return "CL_PLATFORM_NOT_FOUND_KHR";
    default:
      return "CL error";
  }
}

void check(cl_int err, const char* what) {
  if (err != CL_SUCCESS) {
    throw std::runtime_error(std::string("OpenCL: ") + what + " failed: " + error_name(err) + " (" +
                             std::to_string(err) + ")");
  }
}

// Owning handle for an OpenCL object.
template <class T, cl_int (*Release)(T)>
class Handle {
 public:
  Handle() = default;
  explicit Handle(T h) : h_(h) {}
  Handle(Handle&& o) noexcept : h_(std::exchange(o.h_, nullptr)) {}
  Handle& operator=(Handle&& o) noexcept {
    if (this != &o) {
      reset();
      h_ = std::exchange(o.h_, nullptr);
    }
    return *this;
  }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  ~Handle() { reset(); }
  void reset() {
    if (h_ != nullptr) Release(h_);
    h_ = nullptr;
  }
  [[nodiscard]] T get() const { return h_; }

 private:
  T h_ = nullptr;
};
using Context = Handle<cl_context, clReleaseContext>;
using Queue = Handle<cl_command_queue, clReleaseCommandQueue>;
using Program = Handle<cl_program, clReleaseProgram>;
using Kernel = Handle<cl_kernel, clReleaseKernel>;
using Buffer = Handle<cl_mem, clReleaseMemObject>;
using Event = Handle<cl_event, clReleaseEvent>;

std::vector<cl_platform_id> platforms() {
  cl_uint n = 0;
  const cl_int err = clGetPlatformIDs(0, nullptr, &n);
  if (err == -1001 /* CL_PLATFORM_NOT_FOUND_KHR */ || n == 0) return {};
  check(err, "clGetPlatformIDs");
  std::vector<cl_platform_id> ids(n);
  check(clGetPlatformIDs(n, ids.data(), nullptr), "clGetPlatformIDs");
  return ids;
}

std::vector<cl_device_id> devices_of(cl_platform_id p) {
  cl_uint n = 0;
  if (clGetDeviceIDs(p, CL_DEVICE_TYPE_ALL, 0, nullptr, &n) != CL_SUCCESS || n == 0) return {};
  std::vector<cl_device_id> ids(n);
  check(clGetDeviceIDs(p, CL_DEVICE_TYPE_ALL, n, ids.data(), nullptr), "clGetDeviceIDs");
  return ids;
}

// A string property of an OpenCL object: ask for the size, then the bytes.
template <class Object, class Info>
std::string info_string(cl_int (*get)(Object, Info, std::size_t, void*, std::size_t*), Object o,
                        Info what, const char* name) {
  std::size_t size = 0;
  check(get(o, what, 0, nullptr, &size), name);
  std::string s(size, '\0');
  check(get(o, what, size, s.data(), nullptr), name);
  while (!s.empty() && s.back() == '\0') s.pop_back();
  return s;
}

std::string platform_string(cl_platform_id p, cl_platform_info what) {
  return info_string(clGetPlatformInfo, p, what, "clGetPlatformInfo");
}

std::string device_string(cl_device_id d, cl_device_info what) {
  return info_string(clGetDeviceInfo, d, what, "clGetDeviceInfo");
}

template <class T>
T device_value(cl_device_id d, cl_device_info what) {
  T v{};
  check(clGetDeviceInfo(d, what, sizeof v, &v, nullptr), "clGetDeviceInfo");
  return v;
}

bool has_extension(const std::string& extensions, const char* name) {
  const std::string padded = " " + extensions + " ";
  return padded.find(std::string(" ") + name + " ") != std::string::npos;
}

OpenCLDevice describe(int pi, int di, cl_platform_id p, cl_device_id d) {
  OpenCLDevice o;
  o.platform_index = pi;
  o.device_index = di;
  o.platform = platform_string(p, CL_PLATFORM_NAME);
  o.name = device_string(d, CL_DEVICE_NAME);
  o.version = device_string(d, CL_DEVICE_VERSION);
  const auto type = device_value<cl_device_type>(d, CL_DEVICE_TYPE);
  o.type = (type & CL_DEVICE_TYPE_GPU)           ? "GPU"
           : (type & CL_DEVICE_TYPE_CPU)         ? "CPU"
           : (type & CL_DEVICE_TYPE_ACCELERATOR) ? "ACCELERATOR"
                                                 : "OTHER";
  o.compute_units = device_value<cl_uint>(d, CL_DEVICE_MAX_COMPUTE_UNITS);
  o.global_memory_bytes = device_value<cl_ulong>(d, CL_DEVICE_GLOBAL_MEM_SIZE);
  o.local_memory_bytes = device_value<cl_ulong>(d, CL_DEVICE_LOCAL_MEM_SIZE);
  o.max_work_group_size = device_value<std::size_t>(d, CL_DEVICE_MAX_WORK_GROUP_SIZE);
  const std::string ext = device_string(d, CL_DEVICE_EXTENSIONS);
  o.int64_atomics = has_extension(ext, "cl_khr_int64_base_atomics");
  o.fp64 = has_extension(ext, "cl_khr_fp64");
  o.fp32_rounded_sqrt =
      (device_value<cl_device_fp_config>(d, CL_DEVICE_SINGLE_FP_CONFIG) &
       CL_FP_CORRECTLY_ROUNDED_DIVIDE_SQRT) != 0;
  return o;
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

struct Selected {
  cl_platform_id platform = nullptr;
  cl_device_id device = nullptr;
  OpenCLDevice info;
};

// The device `options` name: platform index, name substring; GPUs before other devices.
Selected select_device(const OpenCLOptions& options) {
  options.validate();
  const auto ps = platforms();
  if (ps.empty()) {
    throw BackendUnavailable(kNoOpenCLPlatform);
  }
  if (options.platform >= static_cast<int>(ps.size())) {
    throw BackendUnavailable("OpenCL back end: --cl-platform " + std::to_string(options.platform) +
                             " does not exist (" + std::to_string(ps.size()) +
                             " platforms; see 'linksight devices')");
  }
  std::vector<Selected> candidates;
  std::string seen, lacking;
  for (int pi = 0; pi < static_cast<int>(ps.size()); ++pi) {
    if (options.platform >= 0 && pi != options.platform) continue;
    const auto ds = devices_of(ps[pi]);
    for (int di = 0; di < static_cast<int>(ds.size()); ++di) {
      Selected s{ps[pi], ds[di], describe(pi, di, ps[pi], ds[di])};
      seen += (seen.empty() ? "" : "; ") + s.info.name;
      if (!options.device.empty() &&
          lower(s.info.name).find(lower(options.device)) == std::string::npos) {
        continue;
      }
      if (!s.info.int64_atomics) {
        lacking += (lacking.empty() ? "" : "; ") + s.info.name;
        continue;
      }
      candidates.push_back(std::move(s));
    }
  }
  if (candidates.empty() && !lacking.empty()) {
    throw BackendUnavailable(
        "OpenCL back end: no usable device: " + lacking +
        " lack cl_khr_int64_base_atomics, which the accumulation kernels need");
  }
  if (candidates.empty()) {
    throw BackendUnavailable(
        "OpenCL back end: no device " +
        (options.device.empty() ? std::string("found") : "matches '" + options.device + "'") +
        (seen.empty() ? std::string(" (the platforms have no devices)")
                      : " (devices: " + seen + ")"));
  }
  std::stable_sort(candidates.begin(), candidates.end(), [](const Selected& a, const Selected& b) {
    return (a.info.type == "GPU") > (b.info.type == "GPU");
  });
  return candidates.front();
}

Program build(cl_context ctx, cl_device_id dev, const char* source,
              const std::string& device_name, const std::string& options = "-cl-std=CL1.2") {
  cl_int err = CL_SUCCESS;
  Program program(clCreateProgramWithSource(ctx, 1, &source, nullptr, &err));
  check(err, "clCreateProgramWithSource");
  err = clBuildProgram(program.get(), 1, &dev, options.c_str(), nullptr, nullptr);
  if (err != CL_SUCCESS) {
    std::size_t size = 0;
    clGetProgramBuildInfo(program.get(), dev, CL_PROGRAM_BUILD_LOG, 0, nullptr, &size);
    std::string log(size, '\0');
    clGetProgramBuildInfo(program.get(), dev, CL_PROGRAM_BUILD_LOG, size, log.data(), nullptr);
    while (!log.empty() && (log.back() == '\0' || log.back() == '\n')) log.pop_back();
    throw std::runtime_error("OpenCL: kernel build failed on '" + device_name + "' (" +
                             error_name(err) + "); build log:\n" + log);
  }
  return program;
}

class OpenCLBackend final : public Backend, public ChainPassDevice {
 public:
  explicit OpenCLBackend(const OpenCLOptions& options) : options_(options) {
    const Selected sel = select_device(options);
    info_ = sel.info;
    device_ = sel.device;
    if (!info_.int64_atomics) {
      throw BackendUnavailable("OpenCL back end: device '" + info_.name +
                               "' lacks cl_khr_int64_base_atomics, which the accumulation "
                               "kernels need");
    }
    cl_int err = CL_SUCCESS;
    const cl_context_properties props[] = {
        CL_CONTEXT_PLATFORM, reinterpret_cast<cl_context_properties>(sel.platform), 0};
    context_ = Context(clCreateContext(props, 1, &device_, nullptr, nullptr, &err));
    check(err, "clCreateContext");
    queue_ = Queue(clCreateCommandQueue(context_.get(), device_, CL_QUEUE_PROFILING_ENABLE, &err));
    check(err, "clCreateCommandQueue");
    program_ = build(context_.get(), device_, detail::kSomKernelSource, info_.name);
    for (auto [kernel, name] :
         {std::pair{&k_associate_, "associate"}, std::pair{&k_atomic_, "accumulate_atomic"},
          std::pair{&k_groups_, "accumulate_groups"}, std::pair{&k_partials_, "sum_partials"}}) {
      *kernel = Kernel(clCreateKernel(program_.get(), name, &err));
      check(err, "clCreateKernel");
    }
    // The work-group size must suit every kernel and the device's first dimension.
    std::size_t limit = info_.max_work_group_size;
    for (const Kernel* k : {&k_associate_, &k_atomic_, &k_groups_, &k_partials_}) {
      std::size_t kernel_max = 0;
      check(clGetKernelWorkGroupInfo(k->get(), device_, CL_KERNEL_WORK_GROUP_SIZE,
                                     sizeof kernel_max, &kernel_max, nullptr),
            "clGetKernelWorkGroupInfo");
      limit = std::min(limit, kernel_max);
    }
    cl_uint dims = 0;
    check(clGetDeviceInfo(device_, CL_DEVICE_MAX_WORK_ITEM_DIMENSIONS, sizeof dims, &dims, nullptr),
          "clGetDeviceInfo");
    std::vector<std::size_t> item_sizes(std::max<cl_uint>(dims, 1));
    check(clGetDeviceInfo(device_, CL_DEVICE_MAX_WORK_ITEM_SIZES,
                          item_sizes.size() * sizeof(std::size_t), item_sizes.data(), nullptr),
          "clGetDeviceInfo");
    limit = std::min(limit, item_sizes[0]);
    wg_ = options.work_group_size > 0 ? options.work_group_size : std::min<std::size_t>(256, limit);
    if (wg_ > limit) {
      throw std::invalid_argument("OpenCLOptions.work_group_size = " + std::to_string(wg_) +
                                  ": device '" + info_.name + "' allows at most " +
                                  std::to_string(limit));
    }
    // chain-fit's passes need double precision and a correctly rounded float square root
    // (OpenCL allows -cl-fp32-correctly-rounded-divide-sqrt only where the device reports
    // it); without them, or should its kernels not build here, they run on the host
    // (chain_pass_device() is null) and paper mode's kernels are unaffected.
    if (info_.fp64 && info_.fp32_rounded_sqrt) {
      try {
        build_chain_kernels(limit);
      } catch (const std::runtime_error&) {  // the host fits
        k_chain_point_.reset();
        k_chain_sums_.reset();
        chain_program_.reset();
      }
    }
  }

  BackendKind kind() const override { return BackendKind::opencl; }

  void set_points(const PointsView& p) override {
    // Nothing of the previous frame survives, even if this upload fails part-way.
    n_ = 0;
    device_seconds_ = 0.0;
    assoc_valid_ = false;
    has_pass_ = false;
    events_.clear();
    const std::size_t n = p.size();
    if (n == 0) return;
    // All four point buffers share one capacity: float and cl_int are both 4 bytes.
    static_assert(sizeof(float) == sizeof(cl_int));
    for (Buffer* buf : {&x_, &y_, &z_, &assoc_buf_}) grow(*buf, n * sizeof(float), cap_points_);
    cap_points_ = std::max(cap_points_, n * sizeof(float));
    // Blocking writes: the caller's arrays may change once this returns.
    for (auto [buf, src] :
         {std::pair{&x_, p.x.data()}, std::pair{&y_, p.y.data()}, std::pair{&z_, p.z.data()}}) {
      check(clEnqueueWriteBuffer(queue_.get(), buf->get(), CL_TRUE, 0, n * sizeof(float), src, 0,
                                 nullptr, nullptr),
            "upload points");
    }
    n_ = n;  // only now are the buffers valid for n points
  }

  void associate(const std::vector<float>& q, Accumulation& acc) override {
    const int m = static_cast<int>(q.size() / 3);
    if (m < 1) throw std::invalid_argument("OpenCL back end: associate() needs at least one node");
    acc.reset(m);
    assoc_valid_ = false;
    has_pass_ = true;
    events_.clear();
    if (n_ == 0) return;
    const std::size_t m4 = 4 * static_cast<std::size_t>(m);
    if (options_.accumulation == ClAccumulation::reduction &&
        m4 * sizeof(cl_long) > info_.local_memory_bytes) {
      throw std::runtime_error("OpenCL: " + std::to_string(m) +
                               " nodes do not fit the local memory of '" + info_.name + "'");
    }
    std::size_t cap_q = q_bytes_, cap_acc = acc_bytes_, cap_partial = partial_bytes_;
    grow(q_buf_, q.size() * sizeof(float), cap_q);
    grow(acc_buf_, m4 * sizeof(cl_long), cap_acc);
    q_bytes_ = std::max(q_bytes_, q.size() * sizeof(float));
    acc_bytes_ = std::max(acc_bytes_, m4 * sizeof(cl_long));
    const cl_uint n = static_cast<cl_uint>(n_);
    const std::size_t global = (n_ + wg_ - 1) / wg_ * wg_;

    check(clEnqueueWriteBuffer(queue_.get(), q_buf_.get(), CL_TRUE, 0, q.size() * sizeof(float),
                               q.data(), 0, nullptr, nullptr),
          "upload nodes");
    set_args(k_associate_.get(), x_.get(), y_.get(), z_.get(), n, q_buf_.get(),
             static_cast<cl_int>(m), assoc_buf_.get());
    run(k_associate_.get(), global, wg_);  // kernel 1
    const cl_long zero = 0;
    check(clEnqueueFillBuffer(queue_.get(), acc_buf_.get(), &zero, sizeof zero, 0,
                              m4 * sizeof(cl_long), 0, nullptr, nullptr),
          "clear sums");
    if (options_.accumulation == ClAccumulation::atomic) {
      set_args(k_atomic_.get(), x_.get(), y_.get(), z_.get(), assoc_buf_.get(), n, acc_buf_.get());
      run(k_atomic_.get(), global, wg_);  // kernel 2, paper's form
    } else {
      const std::size_t groups = std::min(kMaxGroups, global / wg_);
      grow(partial_buf_, groups * m4 * sizeof(cl_long), cap_partial);
      partial_bytes_ = std::max(partial_bytes_, groups * m4 * sizeof(cl_long));
      set_args(k_groups_.get(), x_.get(), y_.get(), z_.get(), assoc_buf_.get(), n,
               static_cast<cl_int>(m));
      check(clSetKernelArg(k_groups_.get(), 6, m4 * sizeof(cl_long), nullptr),
            "clSetKernelArg local");
      const cl_mem partial = partial_buf_.get();
      check(clSetKernelArg(k_groups_.get(), 7, sizeof partial, &partial), "clSetKernelArg");
      run(k_groups_.get(), groups * wg_, wg_);  // kernel 2, per-group partials
      set_args(k_partials_.get(), partial_buf_.get(), static_cast<cl_uint>(groups),
               static_cast<cl_int>(m4), acc_buf_.get());
      run(k_partials_.get(), (m4 + wg_ - 1) / wg_ * wg_, wg_);
    }
    fixed_.resize(m4);
    check(clEnqueueReadBuffer(queue_.get(), acc_buf_.get(), CL_TRUE, 0, m4 * sizeof(cl_long),
                              fixed_.data(), 0, nullptr, nullptr),
          "read sums");
    collect_profile();
    for (int j = 0; j < m; ++j) {
      for (int a = 0; a < 3; ++a)
        acc.sum[3 * j + a] = fixed_[4 * j + a];  // the CPU back ends use the same units
      acc.count[j] = fixed_[4 * j + 3];
    }
  }

  std::span<const std::int32_t> association() override {
    if (!has_pass_) return {};  // no pass over the current points yet
    if (!assoc_valid_) {
      assoc_host_.resize(n_);
      if (n_ > 0) {
        check(clEnqueueReadBuffer(queue_.get(), assoc_buf_.get(), CL_TRUE, 0, n_ * sizeof(cl_int),
                                  assoc_host_.data(), 0, nullptr, nullptr),
              "read associations");
      }
      assoc_valid_ = true;
    }
    return assoc_host_;
  }

  double device_seconds() const override { return device_seconds_; }

  ChainPassDevice* chain_pass_device() override {
    return chain_program_.get() != nullptr ? this : nullptr;
  }

  void set_chain_points(const PointsView& p) override {
    set_points(p);
    const std::size_t n = p.size();
    if (n == 0) return;
    const std::size_t cap = chain_points_;  // points the buffers hold
    for (Buffer* buf : {&chain_assoc_[0], &chain_assoc_[1]})
      grow(*buf, n * sizeof(cl_short), cap * sizeof(cl_short));
    grow(chain_comp_, n * sizeof(cl_int), cap * sizeof(cl_int));
    grow(chain_val_, n * kChainValues * sizeof(cl_double), cap * kChainValues * sizeof(cl_double));
    chain_points_ = std::max(chain_points_, n);
  }

  detail::ChainSums chain_pass(const detail::ChainFrames& f, const ComponentGeometry& g,
                               const ChainFitParams& params, bool search, int read,
                               int write, std::size_t stride) override {
    const int count = static_cast<int>(f.cx.size());
    detail::ChainSums total(f.cx.size());
    events_.clear();
    if (n_ == 0 || count == 0) return total;
    if (read < 0 || read > 1 || write < 0 || write > 1)
      throw std::invalid_argument("OpenCL chain pass: association buffers are 0 and 1");
    if (stride < 1 || stride > detail::kChainBlock)
      throw std::invalid_argument("OpenCL chain pass: stride " + std::to_string(stride) +
                                  " is not in [1, the block]");
    if (n_ > chain_points_)
      throw std::logic_error("OpenCL chain pass: the points were set by set_points, not "
                             "set_chain_points");
    // The frames, one array after another (chain.cl's CX..T2Z), and the geometry.
    std::vector<cl_double> fr;
    fr.reserve(12 * f.cx.size());
    for (const std::vector<double>* v : {&f.cx, &f.cy, &f.cz, &f.ax, &f.ay, &f.az})
      fr.insert(fr.end(), v->begin(), v->end());
    for (const std::vector<Eigen::Vector3d>* t : {&f.t1, &f.t2})
      for (int a = 0; a < 3; ++a)
        for (const Eigen::Vector3d& v : *t) fr.push_back(v[a]);
    const cl_double geo[5] = {g.ball_radius, g.neck_radius, g.neck_length, params.huber,
                              params.max_distance};
    std::size_t cap_fr = chain_fr_bytes_, cap_geo = 64;
    grow(chain_fr_, fr.size() * sizeof(cl_double), cap_fr);
    chain_fr_bytes_ = std::max(chain_fr_bytes_, fr.size() * sizeof(cl_double));
    grow(chain_geo_, sizeof geo, cap_geo);
    check(clEnqueueWriteBuffer(queue_.get(), chain_fr_.get(), CL_TRUE, 0,
                               fr.size() * sizeof(cl_double), fr.data(), 0, nullptr, nullptr),
          "upload chain");
    check(clEnqueueWriteBuffer(queue_.get(), chain_geo_.get(), CL_TRUE, 0, sizeof geo, geo, 0,
                               nullptr, nullptr),
          "upload geometry");
    const auto n = static_cast<cl_uint>(n_);
    const std::size_t block = detail::kChainBlock;
    set_args(k_chain_point_.get(), x_.get(), y_.get(), z_.get(), n, chain_fr_.get(),
             static_cast<cl_int>(count), chain_geo_.get(), static_cast<cl_int>(search ? 1 : 0),
             chain_assoc_[read].get(), chain_assoc_[write].get(), chain_comp_.get(),
             chain_val_.get(), static_cast<cl_uint>(block), static_cast<cl_uint>(stride));
    run(k_chain_point_.get(), (n_ + chain_wg_ - 1) / chain_wg_ * chain_wg_, chain_wg_);
    const std::size_t blocks = (n_ + block - 1) / block;
    const std::size_t items = blocks * static_cast<std::size_t>(count + 1);
    std::size_t cap_d = chain_out_items_ * 20 * sizeof(cl_double),
                cap_l = chain_out_items_ * sizeof(cl_long);
    grow(chain_out_d_, items * 20 * sizeof(cl_double), cap_d);
    grow(chain_out_l_, items * sizeof(cl_long), cap_l);
    chain_out_items_ = std::max(chain_out_items_, items);
    set_args(k_chain_sums_.get(), chain_comp_.get(), chain_val_.get(), n,
             static_cast<cl_int>(count), static_cast<cl_uint>(block),
             static_cast<cl_uint>(blocks), chain_out_d_.get(), chain_out_l_.get());
    run(k_chain_sums_.get(), (items + chain_wg_ - 1) / chain_wg_ * chain_wg_, chain_wg_);
    chain_d_.resize(items * 20);
    chain_l_.resize(items);
    check(clEnqueueReadBuffer(queue_.get(), chain_out_d_.get(), CL_TRUE, 0,
                              items * 20 * sizeof(cl_double), chain_d_.data(), 0, nullptr, nullptr),
          "read chain sums");
    check(clEnqueueReadBuffer(queue_.get(), chain_out_l_.get(), CL_TRUE, 0,
                              items * sizeof(cl_long), chain_l_.data(), 0, nullptr, nullptr),
          "read chain counts");
    collect_profile();
    // The blocks added in order, each as the CPU sums one (chain_fit.cpp's pass).
    const auto K = static_cast<std::size_t>(count);
    for (std::size_t blk = 0; blk < blocks; ++blk) {
      detail::ChainSums s(K);
      for (std::size_t k = 0; k < K; ++k) {
        const double* o = chain_d_.data() + 20 * (blk * (K + 1) + k);
        int e = 0;
        for (int c = 0; c < 5; ++c)
          for (int r2 = c; r2 < 5; ++r2) s.H[k](r2, c) = o[e++];
        for (int c = 0; c < 5; ++c) s.b[k][c] = o[15 + c];
        s.count[k] = chain_l_[blk * (K + 1) + k];
      }
      const double* o = chain_d_.data() + 20 * (blk * (K + 1) + K);
      s.robust = o[0];
      s.sum2 = o[1];
      s.inliers = static_cast<std::size_t>(chain_l_[blk * (K + 1) + K]);
      total.add(s);
    }
    return total;
  }

 private:
  // chain.cl's program and kernels; throws std::runtime_error when they do not build.
  void build_chain_kernels(std::size_t limit) {
    cl_int err = CL_SUCCESS;
    chain_program_ = build(context_.get(), device_, detail::kChainKernelSource, info_.name,
                           "-cl-std=CL1.2 -cl-fp32-correctly-rounded-divide-sqrt -DVALS=" +
                               std::to_string(detail::kChainValues));
    std::size_t chain_limit = limit;
    for (auto [kernel, name] :
         {std::pair{&k_chain_point_, "chain_point"}, std::pair{&k_chain_sums_, "chain_sums"}}) {
      *kernel = Kernel(clCreateKernel(chain_program_.get(), name, &err));
      check(err, "clCreateKernel");
      std::size_t kernel_max = 0;
      check(clGetKernelWorkGroupInfo(kernel->get(), device_, CL_KERNEL_WORK_GROUP_SIZE,
                                     sizeof kernel_max, &kernel_max, nullptr),
            "clGetKernelWorkGroupInfo");
      chain_limit = std::min(chain_limit, kernel_max);
    }
    chain_wg_ = std::min(wg_, chain_limit);
  }

  static constexpr auto kChainValues = static_cast<std::size_t>(detail::kChainValues);

  // Reallocates `buf` when `bytes` exceeds `capacity` (buffers only grow).
  void grow(Buffer& buf, std::size_t bytes, std::size_t capacity) {
    if (buf.get() != nullptr && bytes <= capacity) return;
    cl_int err = CL_SUCCESS;
    buf = Buffer(clCreateBuffer(context_.get(), CL_MEM_READ_WRITE, std::max<std::size_t>(bytes, 64),
                                nullptr, &err));
    check(err, "clCreateBuffer");
  }

  template <class... Args>
  void set_args(cl_kernel k, const Args&... args) {
    cl_uint i = 0;
    (check(clSetKernelArg(k, i++, sizeof(args), &args), "clSetKernelArg"), ...);
  }

  void run(cl_kernel k, std::size_t global, std::size_t local) {
    cl_event e = nullptr;
    check(clEnqueueNDRangeKernel(queue_.get(), k, 1, nullptr, &global, &local, 0, nullptr, &e),
          "clEnqueueNDRangeKernel");
    events_.emplace_back(e);
  }

  void collect_profile() {
    for (const Event& e : events_) {
      cl_ulong start = 0, end = 0;
      if (clGetEventProfilingInfo(e.get(), CL_PROFILING_COMMAND_START, sizeof start, &start,
                                  nullptr) == CL_SUCCESS &&
          clGetEventProfilingInfo(e.get(), CL_PROFILING_COMMAND_END, sizeof end, &end, nullptr) ==
              CL_SUCCESS &&
          end > start) {
        device_seconds_ += static_cast<double>(end - start) * 1e-9;
      }
    }
    events_.clear();
  }

  OpenCLOptions options_;
  OpenCLDevice info_;
  cl_device_id device_ = nullptr;
  Context context_;
  Queue queue_;
  Program program_;
  Kernel k_associate_, k_atomic_, k_groups_, k_partials_;
  std::size_t wg_ = 0;
  // chain-fit's passes (chain.cl), when the device has double precision.
  Program chain_program_;
  Kernel k_chain_point_, k_chain_sums_;
  std::size_t chain_wg_ = 0;
  Buffer chain_assoc_[2], chain_comp_, chain_val_, chain_fr_, chain_geo_, chain_out_d_,
      chain_out_l_;
  std::size_t chain_points_ = 0, chain_fr_bytes_ = 0, chain_out_items_ = 0;
  std::vector<cl_double> chain_d_;
  std::vector<cl_long> chain_l_;
  Buffer x_, y_, z_, assoc_buf_, q_buf_, acc_buf_, partial_buf_;
  std::size_t cap_points_ = 0, q_bytes_ = 0, acc_bytes_ = 0, partial_bytes_ = 0;
  std::size_t n_ = 0;
  std::vector<cl_long> fixed_;
  std::vector<std::int32_t> assoc_host_;
  bool assoc_valid_ = false;
  bool has_pass_ = false;
  std::vector<Event> events_;
  double device_seconds_ = 0.0;
};

}  // namespace

std::unique_ptr<Backend> make_opencl_backend(const OpenCLOptions& options) {
  return std::make_unique<OpenCLBackend>(options);
}

bool opencl_built() { return true; }

std::vector<OpenCLDevice> opencl_devices() {
  std::vector<OpenCLDevice> out;
  const auto ps = platforms();
  for (int pi = 0; pi < static_cast<int>(ps.size()); ++pi) {
    const auto ds = devices_of(ps[pi]);
    for (int di = 0; di < static_cast<int>(ds.size()); ++di)
      out.push_back(describe(pi, di, ps[pi], ds[di]));
  }
  return out;
}

BackendKind auto_backend() {
  for (const OpenCLDevice& d : opencl_devices()) {
    if (d.type == "GPU" && d.int64_atomics) return BackendKind::opencl;
  }
  return BackendKind::openmp;
}

void check_opencl_build(const std::string& source, const OpenCLOptions& options) {
  const Selected sel = select_device(options);
  cl_int err = CL_SUCCESS;
  const cl_context_properties props[] = {CL_CONTEXT_PLATFORM,
                                         reinterpret_cast<cl_context_properties>(sel.platform), 0};
  Context ctx(clCreateContext(props, 1, &sel.device, nullptr, nullptr, &err));
  check(err, "clCreateContext");
  (void)build(ctx.get(), sel.device, source.c_str(), sel.info.name);
}

}  // namespace linksight
