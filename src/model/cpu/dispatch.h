#pragma once
// The LibTorch side's helpers for calling the kernels of kernels.h (not included by the
// instruction-set files).
#include <ATen/Parallel.h>

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

// Whether the kernel set `isa` takes inputs of `dtype`: bf16 only AVX-512 BF16's, float
// AVX-512's and AVX2's.
inline bool kernel_takes(CpuIsa isa, torch::ScalarType dtype) {
  return isa == CpuIsa::Avx512Bf16 ? dtype == torch::kBFloat16 : dtype == torch::kFloat32 && isa >= CpuIsa::Avx2;
}

// The kernel set for inputs of `dtype` on this CPU, or none (other dtypes, an older CPU).
inline std::optional<CpuIsa> kernel_isa(torch::ScalarType dtype) {
  const CpuFeatures& cpu = cpu_features();
  for (CpuIsa isa : {CpuIsa::Avx512Bf16, CpuIsa::Avx512, CpuIsa::Avx2})
    if (cpu.has(isa) && kernel_takes(isa, dtype)) return isa;
  return std::nullopt;
}

}  // namespace ii::cpu_kernels
