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
  torch::Tensor out = torch::empty_like(q);
  for (int64_t start = 0; start < N; start += chunk) {
    const int64_t len = std::min(chunk, N - start);
    const torch::Tensor qc = q.narrow(2, start, len);
    // Softmax in float32 even for bf16 inputs: the scores' dynamic range needs it.
    torch::Tensor scores = torch::matmul(qc, kt).to(torch::kFloat32).mul_(scale);
    scores = torch::softmax(scores, -1).to(q.scalar_type());
    out.narrow(2, start, len).copy_(torch::matmul(scores, v));
  }
  return out;
}

torch::Tensor naive_attention(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v) {
  const double scale = 1.0 / std::sqrt(static_cast<double>(q.size(3)));
  return torch::matmul(torch::softmax(torch::matmul(q, k.transpose(-2, -1)) * scale, -1), v);
}

torch::Tensor attention(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v) {
  if constexpr (compat::has_fused_sdpa) return compat::fused_sdpa(q, k, v);
  return chunked_attention(q, k, v);
}

}  // namespace ii
