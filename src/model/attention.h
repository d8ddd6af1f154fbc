#pragma once
// Global multi-head attention whose memory grows linearly with the token count (4 views of
// 512 x 904 are 28,928 tokens; the full score matrix would need 53 GB in float32 for 16
// heads).
#include <optional>
#include <string>

#include "common/cpu_features.h"
#include "common/torch.h"

namespace ii {

// How attention is computed; every form gives the same values up to float rounding.
enum class AttentionForm {
  Fastest,  // the fused CPU kernel where it applies, LibTorch's fused kernels on a GPU, else Chunked
  Chunked,  // LibTorch calls over blocks of queries: the reference twin of the fused CPU kernel
  Full,     // the textbook form with the whole score matrix (the benchmarks' baseline)
};

// q, k, v: (B, heads, N, head_dim), rows of head_dim contiguous or not. Softmax scale
// 1/sqrt(head_dim). Returns (B, heads, N, head_dim) in the dtype of q; Fastest on the CPU
// returns a view of a (B, N, heads, head_dim) tensor, so merging the heads afterwards is free.
torch::Tensor attention(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v,
                        AttentionForm form = AttentionForm::Fastest);

// Why q, k and v are not one problem a forward-only attention kernel can take, or empty: each
// must be 4-D (B, heads, N, head_dim), k and v alike and matching q, with no gradients wanted.
// The fused CPU kernel checks this before what is its own.
std::string forward_kernel_input_refusal(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v);

// The fused CPU kernel (flash-attention form: scores kept in cache, online softmax, bf16 dot
// products with AVX-512 BF16, float FMA with AVX-512 or AVX2; model/cpu/). Which instruction
// set attention() uses for these inputs on this CPU, or none: not on the CPU, a dtype other
// than float32/bf16 (bf16 needs AVX-512 BF16), head_dim over 128, or gradients wanted (the
// kernel has no backward pass; training uses the chunked form).
std::optional<CpuIsa> fused_cpu_attention_isa(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v);
// The fused kernel of one instruction set (tests and benchmarks compare them); throws Error
// if it cannot run these inputs on this CPU.
torch::Tensor fused_cpu_attention(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v, CpuIsa isa);

// The chunked form itself, computed in float for bf16 inputs too (returned in their dtype);
// `max_chunk_bytes` bounds the score block of one chunk.
torch::Tensor chunked_attention(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v,
                                int64_t max_chunk_bytes = 64LL << 20);

// softmax(q k^T / sqrt(d)) v with the whole score matrix materialised.
torch::Tensor naive_attention(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v);

}  // namespace ii
