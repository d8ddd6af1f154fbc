#pragma once
// CUDA back end of render() on raw device pointers: no LibTorch, so the kernels build with
// nvcc alone and the library links them whether its LibTorch has CUDA or not. All pointers
// are device memory; work runs on the legacy default stream (LibTorch's default current
// stream), and each call returns after its kernels were queued (forward also waits for the
// tile-list length).
//
// Layouts match the CPU back end (src/render/cpu/cpu_rasterizer.h): Splat2D rows of 11
// scalars, PixelBox rows of 4 int32, per-tile Gaussian lists front to back with ties by
// index, `last` as the index within the tile's list (-1 none). Scalars are float, or
// double when SplatInputs::is_double.
#include <cstddef>
#include <cstdint>
#include <functional>

#include "render/splat_math.h"

namespace ii::render_detail::cuda {

struct SplatInputs {
  int64_t count = 0;
  int sh_degree = -1;  // -1: colors are RGB (N,3); else (N, num_coeffs, 3)
  int num_coeffs = 0;
  bool is_double = false;
  int device = 0;  // CUDA device of all pointers; made current for the call
  const void *means = nullptr, *quats = nullptr, *scales = nullptr, *opacities = nullptr, *colors = nullptr;
};

struct ForwardBuffers {
  // Outputs, allocated by the caller.
  void* splats = nullptr;         // N x 11 (splat::kSplatScalars)
  int32_t* boxes = nullptr;       // N x 4
  int64_t* tile_offsets = nullptr;  // tiles + 1
  int32_t* last = nullptr;        // H x W
  void* final_T = nullptr;        // H x W
  void* rgb = nullptr;            // H x W x 3
  void* alpha = nullptr;          // H x W
  void* depth = nullptr;          // H x W
  // Called once with the number of (tile, Gaussian) entries M; returns room for M int32.
  std::function<int32_t*(int64_t)> alloc_tile_gaussians;
  // Temporary device memory that must stay valid until the call returns.
  std::function<void*(size_t)> scratch;
};

// Returns M, the length of the tile list.
int64_t forward(const splat::CameraParams& cam, const SplatInputs& in, const ForwardBuffers& buffers);

struct BackwardBuffers {
  // From the forward pass.
  const void* splats = nullptr;
  const int32_t* boxes = nullptr;
  const int64_t* tile_offsets = nullptr;
  const int32_t* tile_gaussians = nullptr;
  int64_t num_entries = 0;
  const int32_t* last = nullptr;
  const void* final_T = nullptr;
  const void* alpha = nullptr;
  const void* depth = nullptr;
  // Gradients of the outputs (all present; zeros where unused).
  const void* grad_rgb = nullptr;
  const void* grad_alpha = nullptr;
  const void* grad_depth = nullptr;
  // Gradients of the inputs, zero-filled by the caller; shaped like the inputs.
  void *v_means = nullptr, *v_quats = nullptr, *v_scales = nullptr, *v_opacities = nullptr, *v_colors = nullptr;
  std::function<void*(size_t)> scratch;
};

void backward(const splat::CameraParams& cam, const SplatInputs& in, const BackwardBuffers& buffers);

}  // namespace ii::render_detail::cuda
