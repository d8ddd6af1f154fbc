#pragma once
// Global multi-head attention whose memory grows linearly with the token count: queries are
// processed in chunks, so the N x N score matrix never exists at once (4 views of 512 x 904
// are 28,928 tokens; the full matrix would need 53 GB in float32 for 16 heads).
#include "common/torch.h"

namespace ii {

// q, k, v: (B, heads, N, head_dim). Softmax scale 1/sqrt(head_dim). Returns (B, heads, N,
// head_dim) in the dtype of q. On a GPU with LibTorch 2.x: LibTorch's fused kernels (cuDNN,
// Flash). Elsewhere the chunked form below: on a CPU it beat LibTorch 2.6's fused kernel on
// the network's strided q/k/v (release model, 4 x 256², 2 AVX2 cores: docs/benchmarks.md).
torch::Tensor attention(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v);

// The chunked form itself (exposed for tests and benchmarks). `max_chunk_bytes` bounds the
// score block of one chunk.
torch::Tensor chunked_attention(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v,
                                int64_t max_chunk_bytes = 64LL << 20);

// The textbook form, softmax(q k^T / sqrt(d)) v with the whole score matrix materialised:
// the baseline that benchmarks compare against.
torch::Tensor naive_attention(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v);

}  // namespace ii
