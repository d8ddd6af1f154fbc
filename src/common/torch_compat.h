#pragma once
// Every difference between the LibTorch versions we build against lives here: Debian's
// 1.13 (CPU, the CI target) and the 2.x that ships with current PyTorch (GPU machines).
#include <torch/torch.h>

#if defined(TORCH_VERSION_MAJOR) && TORCH_VERSION_MAJOR >= 2
#define II_TORCH2 1
#else
#define II_TORCH2 0
#endif

namespace ii::compat {

// True when at::scaled_dot_product_attention (fused, memory-efficient kernels) exists.
constexpr bool has_fused_sdpa = II_TORCH2;

#if II_TORCH2
inline torch::Tensor fused_sdpa(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v) {
  return at::scaled_dot_product_attention(q, k, v);
}
#else
inline torch::Tensor fused_sdpa(const torch::Tensor&, const torch::Tensor&, const torch::Tensor&) {
  TORCH_CHECK(false, "fused attention needs LibTorch 2.x");
}
#endif

}  // namespace ii::compat
