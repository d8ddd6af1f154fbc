#pragma once
// The CPU kernels of the network's fast path: fused attention (flash-attention form) and
// residual add + layer norm, one set per instruction set. Each set lives in its own
// translation unit (kernels_<set>.cpp) compiled with that set's -m flags, so this interface
// is plain C++: pointers, strides and a function pointer for the thread pool. Those files
// include nothing but the kernel headers, <immintrin.h> and C headers: an inline function of
// a shared header compiled there with AVX-512 could be the copy the linker keeps for every
// other caller (an illegal instruction on an AVX2 CPU).
#include <cstdint>

namespace ii::cpu_kernels {

// softmax(q kᵀ · scale) v for every (batch, head). Rows of q, k, v and out are head_dim
// contiguous elements; element (b, h, n, 0) of a tensor is at base + b*strides[0] +
// h*strides[1] + n*strides[2]. q, k, v and out have the element type of the kernel's input:
// bf16 (as its 16 bits) or float.
struct AttentionProblem {
  int64_t batch = 0, heads = 0, queries = 0, keys = 0, head_dim = 0;
  const void* q = nullptr;
  const void* k = nullptr;
  const void* v = nullptr;
  void* out = nullptr;
  int64_t q_strides[3] = {}, k_strides[3] = {}, v_strides[3] = {}, out_strides[3] = {};
  float scale = 1.0f;
};

// Runs task(context, i) for every i in [0, count), in parallel.
using ParallelFor = void (*)(int64_t count, void (*task)(void* context, int64_t index), void* context);

// The largest head_dim the kernels take (their per-task buffers are sized for it).
constexpr int64_t kMaxHeadDim = 128;

// bf16 inputs and output, bf16 dot products (vdpbf16ps), float softmax and accumulation.
// Each returns false, computing nothing, when its packed copy of k and v cannot be allocated.
bool attention_avx512_bf16(const AttentionProblem& problem, ParallelFor parallel);
// The same with both matrix products on the AMX tiles (tdpbf16ps); softmax in AVX-512.
bool attention_amx_bf16(const AttentionProblem& problem, ParallelFor parallel);
// float inputs and output.
bool attention_avx512_fp32(const AttentionProblem& problem, ParallelFor parallel);
bool attention_avx2_fp32(const AttentionProblem& problem, ParallelFor parallel);

// sum = x + residual and normed = layer_norm(sum) without affine parameters, for `rows`
// contiguous rows of `dim` elements. x and sum are float; residual and normed have the
// kernel's input type. Without a residual (nullptr), normed = layer_norm(x) and sum is unused.
struct AddNormProblem {
  int64_t rows = 0, dim = 0;
  const float* x = nullptr;
  const void* residual = nullptr;
  float* sum = nullptr;
  void* normed = nullptr;
  float eps = 1e-5f;
};

void add_layer_norm_avx512_bf16(const AddNormProblem& problem, ParallelFor parallel);
void add_layer_norm_avx512_fp32(const AddNormProblem& problem, ParallelFor parallel);
void add_layer_norm_avx2_fp32(const AddNormProblem& problem, ParallelFor parallel);

}  // namespace ii::cpu_kernels
