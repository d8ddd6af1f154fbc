#include "model/fp8_attention.h"

#include <algorithm>
#include <cmath>

namespace ii {

torch::Tensor round_to_e4m3(const torch::Tensor& x) {
  const torch::Tensor xf = x.to(torch::kFloat32);
  const torch::Tensor magnitude = xf.abs().clamp_max(kE4m3Max);
  // |x| = m 2^e with m in [0.5, 1): E4M3 values near |x| are 2^(e - 4) apart (3 mantissa bits),
  // and 2^-9 apart below the smallest normal value 2^-6.
  const torch::Tensor exponent = std::get<1>(torch::frexp(magnitude.clamp_min(std::ldexp(1.0f, -6))));
  const torch::Tensor spacing = torch::ldexp(torch::ones_like(magnitude), exponent - 4);
  return torch::copysign(torch::round(magnitude / spacing) * spacing, xf);
}

torch::Tensor e4m3_scale(const torch::Tensor& t) {
  return kE4m3Max / t.to(torch::kFloat32).abs().amax().clamp_min(1e-30);
}

torch::Tensor fp8_emulated_attention(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v,
                                     int64_t max_chunk_bytes) {
  const int64_t B = q.size(0), H = q.size(1), N = q.size(2), Nk = k.size(2);
  const torch::Tensor scale_q = e4m3_scale(q), scale_k = e4m3_scale(k), scale_v = e4m3_scale(v);
  const torch::Tensor q8 = round_to_e4m3(q.to(torch::kFloat32) * scale_q);
  const torch::Tensor k8t = round_to_e4m3(k.to(torch::kFloat32) * scale_k).transpose(-2, -1);
  const torch::Tensor v8 = round_to_e4m3(v.to(torch::kFloat32) * scale_v);
  const torch::Tensor score_scale = 1.0 / (scale_q * scale_k * std::sqrt(static_cast<double>(q.size(3))));

  const int64_t bytes_per_row = B * H * Nk * static_cast<int64_t>(sizeof(float));
  const int64_t chunk =
      std::clamp<int64_t>(max_chunk_bytes / std::max<int64_t>(bytes_per_row, 1), 1, std::max<int64_t>(N, 1));
  torch::Tensor out = torch::empty(q.sizes(), q.options().dtype(torch::kFloat32));
  for (int64_t start = 0; start < N; start += chunk) {
    const int64_t len = std::min(chunk, N - start);
    // E4M3 products are exact in float and the sums run in float, as in the kernel.
    const torch::Tensor scores = torch::matmul(q8.narrow(2, start, len), k8t) * score_scale;
    const torch::Tensor p = torch::exp(scores - std::get<0>(scores.max(-1, true)));
    const torch::Tensor row_sum = p.sum(-1, true);
    const torch::Tensor pv = torch::matmul(round_to_e4m3(p * kE4m3Max), v8);
    // The output in v8's units (|o| <= 448: the output scale is v's), rounded, then in v's.
    out.narrow(2, start, len).copy_(round_to_e4m3(pv / (kE4m3Max * row_sum)) / scale_v);
  }
  return out.to(q.scalar_type());
}

}  // namespace ii
