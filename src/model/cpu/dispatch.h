#pragma once
// The LibTorch side's helpers for calling the kernels of kernels.h (not included by the
// instruction-set files).
#include <ATen/Parallel.h>

#include <nlohmann/json.hpp>
#include <optional>

#include "common/cpu_features.h"
#include "common/parallel.h"
#include "common/torch.h"
#include "model/cpu/kernels.h"

namespace ii::cpu_kernels {

// The kernels' thread pool: LibTorch's intra-op thread count.
inline void parallel_tasks(int64_t count, void (*task)(void*, int64_t), void* context) {
  parallel_dynamic(count, at::get_num_threads(), [&](int64_t i) { task(context, i); });
}

// Whether the kernel set `isa` takes inputs of `dtype`: bf16 only AMX's and AVX-512 BF16's,
// float AVX-512's and AVX2's.
inline bool kernel_takes(CpuIsa isa, torch::ScalarType dtype) {
  return isa >= CpuIsa::Avx512Bf16 ? dtype == torch::kBFloat16 : dtype == torch::kFloat32 && isa >= CpuIsa::Avx2;
}

// The kernel set for inputs of `dtype` on this CPU, or none (other dtypes, an older CPU).
inline std::optional<CpuIsa> kernel_isa(torch::ScalarType dtype) {
  const CpuFeatures& cpu = cpu_features();
  for (CpuIsa isa : {CpuIsa::Amx, CpuIsa::Avx512Bf16, CpuIsa::Avx512, CpuIsa::Avx2})
    if (cpu.has(isa) && kernel_takes(isa, dtype)) return isa;
  return std::nullopt;
}

// What run.json and metrics.json record of the CPU: the instruction sets detected and the kernel
// set of the network's attention for inputs of `dtype` ("none": LibTorch's chunked form; the norms
// take the same set, AVX-512 BF16's where it is AMX).
inline nlohmann::json describe_cpu_kernels(torch::ScalarType dtype) {
  const std::optional<CpuIsa> isa = kernel_isa(dtype);
  return {{"detected", cpu_isa_name(cpu_features().isa)},
          {"amx_bf16", cpu_features().amx_bf16},
          {"kernels", isa ? cpu_isa_name(*isa) : "none"}};
}

// An attention kernel of kernels.h, or a test's model of one.
using AttentionKernel = bool (*)(const AttentionProblem& problem, ParallelFor parallel);

// q, k, v (B, heads, N, head_dim) through `kernel`: what fused_cpu_attention (model/attention.h)
// does once it has checked the inputs and chosen the kernel. Returns (B, heads, N, head_dim), a
// view of a (B, N, heads, head_dim) tensor.
torch::Tensor run_attention_kernel(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v,
                                   AttentionKernel kernel);

}  // namespace ii::cpu_kernels
