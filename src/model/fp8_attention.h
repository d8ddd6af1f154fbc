#pragma once
// Attention with its two matrix products in FP8 E4M3 (1 sign, 4 exponent and 3 mantissa bits;
// the largest finite value is 448), scaled per tensor the way cuDNN's FP8 attention takes it
// on Hopper GPUs: twice bf16's arithmetic rate, at the cost of about 2 significant digits.
//   q, k, v   each multiplied by 448 / max|t| and rounded to E4M3;
//   P         exp(scores - row max), in [0, 1], multiplied by 448 and rounded to E4M3 (the
//             row sums are taken before rounding);
//   out       (P v) / row sum, rounded to E4M3 with the scale 448 / max|v| (every output is an
//             average of rows of v, so |out| <= max|v|), returned in q's dtype.
#include <string>

#include "common/torch.h"

namespace ii {

constexpr float kE4m3Max = 448.0f;

// Each element rounded to the nearest E4M3 value (ties to even), saturating at +-448: what a
// cast to float8_e4m3fn keeps of a float, as a float tensor on x's device.
torch::Tensor round_to_e4m3(const torch::Tensor& x);

// The per-tensor scale 448 / max|t|, a float scalar tensor on t's device (nothing waits for a GPU).
torch::Tensor e4m3_scale(const torch::Tensor& t);

// The computation above in float with LibTorch operations, on any device and LibTorch: FP8's
// error measured where no FP8 kernel runs (a CPU, a GPU older than Hopper). q, k, v:
// (B, heads, N, head_dim); returns (B, heads, N, head_dim). Memory as chunked_attention's.
torch::Tensor fp8_emulated_attention(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v,
                                     int64_t max_chunk_bytes = 64LL << 20);

// cuDNN's FP8 attention kernel (model/cuda/fp8_attention_cudnn.cpp): built with the GPU
// configuration (scripts/gpu/build.sh, which brings the cuDNN frontend's headers), runs on
// Hopper or newer GPUs. Why it cannot run these inputs here, or empty.
std::string cudnn_fp8_attention_refusal(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v);
// Returns a (B, heads, N, head_dim) view of a (B, N, heads, head_dim) tensor in q's dtype (the
// heads merge for free). Throws Error with the refusal's reason or cuDNN's message.
torch::Tensor cudnn_fp8_attention(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v);

}  // namespace ii
