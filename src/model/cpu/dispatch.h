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

// The kernel set for inputs of `dtype` on this CPU: bf16 needs AVX-512 BF16; float takes
// AVX-512 or AVX2. None for other dtypes or an older CPU.
inline std::optional<CpuIsa> kernel_isa(torch::ScalarType dtype) {
  const CpuFeatures& cpu = cpu_features();
  if (dtype == torch::kBFloat16 && cpu.has(CpuIsa::Avx512Bf16)) return CpuIsa::Avx512Bf16;
  if (dtype == torch::kFloat32 && cpu.has(CpuIsa::Avx2)) return cpu.has(CpuIsa::Avx512) ? CpuIsa::Avx512 : CpuIsa::Avx2;
  return std::nullopt;
}

}  // namespace ii::cpu_kernels
