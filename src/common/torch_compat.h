#pragma once
// Every difference between the LibTorch versions we build against lives here: Debian's
// 1.13 (CPU, the CI target) and the 2.x that ships with current PyTorch (GPU machines).
#include "common/torch.h"

#if defined(TORCH_VERSION_MAJOR) && TORCH_VERSION_MAJOR >= 2
#define II_TORCH2 1
#else
#define II_TORCH2 0
#endif

// A CUDA build of LibTorch (its generated ATen/cuda/CUDAConfig.h exists only there): CUDA
// graphs, streams and the NCCL backend can be compiled.
#if __has_include(<ATen/cuda/CUDAConfig.h>)
#define II_HAS_CUDA_TORCH 1
#else
#define II_HAS_CUDA_TORCH 0
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

// ---- c10d process groups (data-parallel training) ---------------------------------------
// Gloo (CPU) needs the gloo headers: Debian ships them in libgloo-dev, LibTorch 2.x zips
// bundle them. NCCL needs a CUDA LibTorch (II_HAS_CUDA_TORCH).
// Both headers are compiled only when their macro is defined, which LibTorch leaves to the
// consumer: define it before including them (see train/distributed.cpp).
#if __has_include(<torch/csrc/distributed/c10d/ProcessGroupGloo.hpp>) && __has_include(<gloo/algorithm.h>)
#define II_HAS_C10D_GLOO 1
#else
#define II_HAS_C10D_GLOO 0
#endif
#if __has_include(<torch/csrc/distributed/c10d/ProcessGroupNCCL.hpp>) && II_HAS_CUDA_TORCH
#define II_HAS_C10D_NCCL 1
#else
#define II_HAS_C10D_NCCL 0
#endif

// TCPStoreOptions::useLibUV exists from LibTorch 2.1 and is on by default from 2.4; a build
// without libuv (Debian's 2.x) refuses it at construction (train/distributed.cpp falls back).
#if defined(TORCH_VERSION_MAJOR) && (TORCH_VERSION_MAJOR > 2 || (TORCH_VERSION_MAJOR == 2 && TORCH_VERSION_MINOR >= 1))
#define II_TCPSTORE_HAS_LIBUV_OPTION 1
#else
#define II_TCPSTORE_HAS_LIBUV_OPTION 0
#endif

namespace c10d {
class ProcessGroup;
class Backend;
}  // namespace c10d

namespace ii::compat {
// The class a Gloo/NCCL process group object is used through: 1.13's backends derive from
// c10d::ProcessGroup, 2.x's from c10d::Backend (ProcessGroup became a dispatcher above them).
#if II_TORCH2
using CollectiveGroup = c10d::Backend;
#else
using CollectiveGroup = c10d::ProcessGroup;
#endif
}  // namespace ii::compat
