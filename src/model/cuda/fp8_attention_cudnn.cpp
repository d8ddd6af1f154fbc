// cuDNN's FP8 flash attention through the cuDNN frontend (NVIDIA's header-only C++ graph API,
// PyPI's nvidia-cudnn-frontend). Compiled in the GPU configuration only: cmake/cuda.cmake
// defines II_HAVE_CUDNN_FRONTEND where it finds the headers beside a CUDA LibTorch 2.x; every
// other build keeps the refusal below and attention() emulates FP8 instead.
#include "common/error.h"
#include "common/torch_compat.h"
#include "model/attention.h"
#include "model/fp8_attention.h"

#if II_HAVE_CUDNN_FRONTEND && II_TORCH2 && II_HAS_CUDA_TORCH
#define II_CUDNN_FP8 1
#else
#define II_CUDNN_FP8 0
#endif

#if II_CUDNN_FP8
#include <ATen/cuda/CUDAContext.h>
#include <ATen/cudnn/Handle.h>
#include <c10/cuda/CUDAGuard.h>
#include <cuda_runtime_api.h>
#include <cudnn_frontend.h>
#include <dlfcn.h>

#include <cstdlib>
#include <map>
#include <memory>
#include <mutex>
#include <tuple>

// The frontend finds cuDNN through this handle (NV_CUDNN_FRONTEND_USE_DYNAMIC_LOADING): the
// libcudnn.so.9 that LibTorch's CUDA library loaded, so nothing here links cuDNN or needs its
// folder on the loader's path.
namespace cudnn_frontend {
void* cudnn_dlhandle = nullptr;
}

#endif

namespace ii {

#if II_CUDNN_FP8
namespace {

namespace fe = ::cudnn_frontend;
using TensorAttr = std::shared_ptr<fe::graph::Tensor_attributes>;

// One built graph per problem shape and device (building one takes cuDNN's heuristics and
// plan compilation: tens of milliseconds, once).
struct Fp8Plan {
  std::shared_ptr<fe::graph::Graph> graph;
  TensorAttr q, k, v, o, descale_q, descale_k, descale_v, descale_s, scale_o, amax_s, amax_o;
  int64_t workspace_bytes = 0;
  std::string error;  // why cuDNN refused the shape, kept so it is not asked again
};
using PlanKey = std::tuple<int, int64_t, int64_t, int64_t, int64_t, int64_t>;  // device, B, H, N, Nk, d

std::string check(fe::error_t status, const char* what) {
  return status.is_good() ? std::string() : fmt::format("cuDNN {}: {}", what, status.get_message());
}

Fp8Plan build_plan(int64_t B, int64_t H, int64_t N, int64_t Nk, int64_t d) {
  Fp8Plan p;
  p.graph = std::make_shared<fe::graph::Graph>();
  fe::graph::Graph& g = *p.graph;
  g.set_io_data_type(fe::DataType_t::FP8_E4M3)
      .set_intermediate_data_type(fe::DataType_t::FLOAT)
      .set_compute_data_type(fe::DataType_t::FLOAT);
  auto operand = [&](const char* name, int64_t rows) {
    return g.tensor(fe::graph::Tensor_attributes()
                        .set_name(name)
                        .set_dim({B, H, rows, d})
                        .set_stride({H * rows * d, rows * d, d, 1}));  // contiguous (B, H, rows, d)
  };
  auto scalar = [&](const char* name) {
    return g.tensor(fe::graph::Tensor_attributes()
                        .set_name(name)
                        .set_dim({1, 1, 1, 1})
                        .set_stride({1, 1, 1, 1})
                        .set_data_type(fe::DataType_t::FLOAT));
  };
  p.q = operand("q", N);
  p.k = operand("k", Nk);
  p.v = operand("v", Nk);
  p.descale_q = scalar("descale_q");
  p.descale_k = scalar("descale_k");
  p.descale_v = scalar("descale_v");
  p.descale_s = scalar("descale_s");
  p.scale_o = scalar("scale_o");
  const TensorAttr scale_s = g.tensor(kE4m3Max);  // P in [0, 1] scaled to E4M3's range
  auto options = fe::graph::SDPA_fp8_attributes()
                     .set_name("fp8_attention")
                     .set_generate_stats(false)
                     .set_attn_scale(static_cast<float>(1.0 / std::sqrt(static_cast<double>(d))));
  auto [o, stats, amax_s, amax_o] = g.sdpa_fp8(p.q, p.k, p.v, p.descale_q, p.descale_k, p.descale_v, p.descale_s,
                                               scale_s, p.scale_o, options);
  (void)stats;
  // (B, N, H, d) in memory: the heads merge into (B, N, H*d) without a copy.
  o->set_output(true)
      .set_dim({B, H, N, d})
      .set_stride({N * H * d, d, H * d, 1})
      .set_data_type(fe::DataType_t::FP8_E4M3);
  for (const TensorAttr& amax : {amax_s, amax_o})
    amax->set_output(true).set_dim({1, 1, 1, 1}).set_stride({1, 1, 1, 1}).set_data_type(fe::DataType_t::FLOAT);
  p.o = o;
  p.amax_s = amax_s;
  p.amax_o = amax_o;

  cudnnHandle_t handle = at::native::getCudnnHandle();
  auto failed = [&](fe::error_t status, const char* what) {
    p.error = check(status, what);
    return !p.error.empty();
  };
  if (failed(g.validate(), "validation") || failed(g.build_operation_graph(handle), "graph") ||
      failed(g.create_execution_plans({fe::HeurMode_t::A}), "plans") || failed(g.check_support(handle), "support") ||
      failed(g.build_plans(handle), "plan build"))
    return p;
  p.error = check(g.get_workspace_size(p.workspace_bytes), "workspace size");
  return p;
}

// The plan of this shape, built on first use; nullptr-free: a refused shape carries its error.
const Fp8Plan& plan_for(const torch::Tensor& q, const torch::Tensor& k) {
  static std::mutex mutex;
  static std::map<PlanKey, Fp8Plan> plans;
  const PlanKey key{q.device().index(), q.size(0), q.size(1), q.size(2), k.size(2), q.size(3)};
  const std::lock_guard<std::mutex> lock(mutex);
  auto it = plans.find(key);
  if (it == plans.end())
    it = plans.emplace(key, build_plan(q.size(0), q.size(1), q.size(2), k.size(2), q.size(3))).first;
  return it->second;
}

// Points the frontend at the process's cuDNN and CUDA runtime; why it cannot, or empty.
std::string load_cudnn() {
  static const std::string error = [] {
    ::cudnn_frontend::cudnn_dlhandle = dlopen("libcudnn.so.9", RTLD_NOW | RTLD_NOLOAD);
    if (!::cudnn_frontend::cudnn_dlhandle) return std::string("libcudnn.so.9 is not loaded (LibTorch loads it)");
    // The frontend would otherwise take the first of libcudart.so.12 and .13 it can open.
    setenv("CUDNN_FRONTEND_CUDART_LIB_NAME", fmt::format("libcudart.so.{}", CUDART_VERSION / 1000).c_str(), 0);
    return std::string();
  }();
  return error;
}

}  // namespace
#endif

std::string cudnn_fp8_attention_refusal(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v) {
#if II_CUDNN_FP8
  if (!q.is_cuda() || !k.is_cuda() || !v.is_cuda()) return "the inputs are not on a CUDA device";
  if (std::string why = forward_kernel_input_refusal(q, k, v); !why.empty()) return why;
  if (q.size(3) % 16 != 0 || q.size(3) > 256)
    return fmt::format("head_dim {} is not a multiple of 16 up to 256", q.size(3));
  const cudaDeviceProp* props = at::cuda::getDeviceProperties(q.device().index());
  if (props->major < 9)
    return fmt::format("{} (compute capability {}.{}) is older than Hopper", props->name, props->major, props->minor);
  if (const std::string why = load_cudnn(); !why.empty()) return why;
  const c10::cuda::CUDAGuard guard(q.device());
  return plan_for(q, k).error;
#else
  (void)q, (void)k, (void)v;
  return "this build has no cuDNN FP8 attention (the GPU configuration, scripts/gpu/build.sh, brings it)";
#endif
}

torch::Tensor cudnn_fp8_attention(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v) {
#if II_CUDNN_FP8
  if (const std::string why = cudnn_fp8_attention_refusal(q, k, v); !why.empty()) fail("FP8 attention: {}", why);
  const c10::cuda::CUDAGuard guard(q.device());
  const Fp8Plan& plan = plan_for(q, k);
  const int64_t B = q.size(0), H = q.size(1), N = q.size(2), d = q.size(3);
  auto to_e4m3 = [](const torch::Tensor& t, const torch::Tensor& scale) {
    return (t.to(torch::kFloat32) * scale).to(at::kFloat8_e4m3fn).contiguous();
  };
  const torch::Tensor scale_q = e4m3_scale(q).reshape({1, 1, 1, 1}), scale_k = e4m3_scale(k).reshape({1, 1, 1, 1}),
                      scale_v = e4m3_scale(v).reshape({1, 1, 1, 1});
  const torch::Tensor q8 = to_e4m3(q, scale_q), k8 = to_e4m3(k, scale_k), v8 = to_e4m3(v, scale_v);
  const torch::Tensor descale_q = 1.0 / scale_q, descale_k = 1.0 / scale_k, descale_v = 1.0 / scale_v;
  const torch::Tensor descale_s = torch::full({1, 1, 1, 1}, 1.0f / kE4m3Max, scale_q.options());
  // Every output is an average of rows of v: v's scale keeps it within E4M3's range.
  const torch::Tensor& scale_o = scale_v;
  torch::Tensor o8 = torch::empty({B, N, H, d}, q8.options());
  torch::Tensor amax = torch::empty({2}, scale_q.options());
  torch::Tensor workspace =
      torch::empty({std::max<int64_t>(plan.workspace_bytes, 1)}, q.options().dtype(torch::kUInt8));
  std::unordered_map<TensorAttr, void*> pack = {
      {plan.q, q8.data_ptr()},
      {plan.k, k8.data_ptr()},
      {plan.v, v8.data_ptr()},
      {plan.o, o8.data_ptr()},
      {plan.descale_q, descale_q.data_ptr()},
      {plan.descale_k, descale_k.data_ptr()},
      {plan.descale_v, descale_v.data_ptr()},
      {plan.descale_s, descale_s.data_ptr()},
      {plan.scale_o, scale_o.data_ptr()},
      {plan.amax_s, amax.data_ptr<float>()},
      {plan.amax_o, amax.data_ptr<float>() + 1},
  };
  if (const std::string error = check(plan.graph->execute(at::native::getCudnnHandle(), pack, workspace.data_ptr()),
                                      "execution");
      !error.empty())
    fail("FP8 attention: {}", error);
  return (o8.to(torch::kFloat32) * descale_v).to(q.scalar_type()).permute({0, 2, 1, 3});
#else
  fail("FP8 attention: {}", cudnn_fp8_attention_refusal(q, k, v));
#endif
}

}  // namespace ii
