#include "model/attention.h"

#include <algorithm>
#include <cmath>

#include "common/torch_compat.h"

namespace ii {

torch::Tensor chunked_attention(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v,
                                int64_t max_chunk_bytes) {
  const int64_t B = q.size(0), H = q.size(1), N = q.size(2), Nk = k.size(2);
  const double scale = 1.0 / std::sqrt(static_cast<double>(q.size(3)));
  const int64_t bytes_per_row = B * H * Nk * static_cast<int64_t>(sizeof(float));
  const int64_t chunk = std::clamp<int64_t>(max_chunk_bytes / std::max<int64_t>(bytes_per_row, 1), 1, N);
  const torch::Tensor kt = k.transpose(-2, -1);
  const bool low_precision = q.scalar_type() == torch::kBFloat16;
  // Scaling q first is exact in bf16 when head_dim is a power of 4 (64: scale 1/8).
  const torch::Tensor qs = q * scale;
  torch::Tensor out = torch::empty_like(q);
  for (int64_t start = 0; start < N; start += chunk) {
    const int64_t len = std::min(chunk, N - start);
    const torch::Tensor scores = torch::matmul(qs.narrow(2, start, len), kt);
    // ATen's bf16 softmax reduces in float internally and is ~8x faster than converting the
    // scores to float first (measured on 16 x 512 x 4096 blocks: 16 ms vs 140 ms).
    const torch::Tensor probs = low_precision ? torch::softmax(scores, -1)
                                              : torch::softmax(scores, -1, torch::kFloat32);
    out.narrow(2, start, len).copy_(torch::matmul(probs, v));
  }
  return out;
}

torch::Tensor naive_attention(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v) {
  const double scale = 1.0 / std::sqrt(static_cast<double>(q.size(3)));
  return torch::matmul(torch::softmax(torch::matmul(q, k.transpose(-2, -1)) * scale, -1), v);
}

torch::Tensor attention(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v) {
  if (compat::has_fused_sdpa && q.is_cuda()) return compat::fused_sdpa(q, k, v);
  return chunked_attention(q, k, v);
}

}  // namespace ii
