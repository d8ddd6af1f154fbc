#include "model/attention.h"

#include <algorithm>
#include <cmath>

#include "common/error.h"
#include "common/torch_compat.h"
#include "model/cpu/dispatch.h"

namespace ii {

torch::Tensor chunked_attention(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v,
                                int64_t max_chunk_bytes) {
  const int64_t B = q.size(0), H = q.size(1), N = q.size(2), Nk = k.size(2);
  const double scale = 1.0 / std::sqrt(static_cast<double>(q.size(3)));
  const int64_t bytes_per_row = B * H * Nk * static_cast<int64_t>(sizeof(float));
  const int64_t chunk = std::clamp<int64_t>(max_chunk_bytes / std::max<int64_t>(bytes_per_row, 1), 1, N);
  // In float whatever the inputs' dtype. LibTorch 1.13's CPU bf16 batched product sums in bf16:
  // over thousands of keys its probabilities times v lost so much that the default model's
  // renders of the statue were 22 dB from float32's (46-48 dB now), and bf16 scores (8
  // significant bits) would weigh a key of score 20 up to 6 % wrong.
  const torch::Tensor kt = k.to(torch::kFloat32).transpose(-2, -1);
  const torch::Tensor vf = v.to(torch::kFloat32);
  torch::Tensor out = torch::empty_like(q);
  for (int64_t start = 0; start < N; start += chunk) {
    const int64_t len = std::min(chunk, N - start);
    const torch::Tensor scores = torch::matmul(q.narrow(2, start, len).to(torch::kFloat32) * scale, kt);
    out.narrow(2, start, len).copy_(torch::matmul(torch::softmax(scores, -1), vf));
  }
  return out;
}

torch::Tensor naive_attention(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v) {
  const double scale = 1.0 / std::sqrt(static_cast<double>(q.size(3)));
  return torch::matmul(torch::softmax(torch::matmul(q, k.transpose(-2, -1)) * scale, -1), v);
}

std::string forward_kernel_input_refusal(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v) {
  if (q.dim() != 4 || k.dim() != 4 || v.dim() != 4) return "q, k and v must be (B, heads, N, head_dim)";
  if (k.sizes() != v.sizes() || q.size(0) != k.size(0) || q.size(1) != k.size(1) || q.size(3) != k.size(3))
    return "q, k and v shapes do not match";
  if (torch::GradMode::is_enabled() && (q.requires_grad() || k.requires_grad() || v.requires_grad()))
    return "gradients are wanted (the kernel has no backward pass)";
  return {};
}

namespace {

// Why the kernel of `isa` cannot run these inputs here, or empty.
std::string fused_cpu_refusal(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v, CpuIsa isa) {
  if (!cpu_features().has(isa)) return fmt::format("this CPU has no {}", cpu_isa_name(isa));
  if (!q.device().is_cpu() || !k.device().is_cpu() || !v.device().is_cpu()) return "the inputs are not on the CPU";
  if (std::string why = forward_kernel_input_refusal(q, k, v); !why.empty()) return why;
  if (q.size(3) > cpu_kernels::kMaxHeadDim)
    return fmt::format("head_dim {} is over {}", q.size(3), cpu_kernels::kMaxHeadDim);
  if (q.scalar_type() != k.scalar_type() || q.scalar_type() != v.scalar_type()) return "q, k and v dtypes differ";
  if (!cpu_kernels::kernel_takes(isa, q.scalar_type()))
    return fmt::format("no {} kernel for {}", cpu_isa_name(isa), c10::toString(q.scalar_type()));
  return {};
}

}  // namespace

namespace cpu_kernels {

torch::Tensor run_attention_kernel(const torch::Tensor& q_in, const torch::Tensor& k_in, const torch::Tensor& v_in,
                                   AttentionKernel kernel) {
  // The kernels read rows of head_dim contiguous elements at any other strides (the network's
  // q, k, v are strided views of one qkv product).
  auto rows = [](const torch::Tensor& t) { return t.stride(3) == 1 ? t : t.contiguous(); };
  const torch::Tensor q = rows(q_in), k = rows(k_in), v = rows(v_in);
  const int64_t B = q.size(0), H = q.size(1), N = q.size(2), d = q.size(3);
  torch::Tensor out = torch::empty({B, N, H, d}, q.options());
  if (out.numel() == 0) return out.permute({0, 2, 1, 3});

  AttentionProblem p;
  p.batch = B;
  p.heads = H;
  p.queries = N;
  p.keys = k.size(2);
  p.head_dim = d;
  p.q = q.data_ptr();
  p.k = k.data_ptr();
  p.v = v.data_ptr();
  p.out = out.data_ptr();
  for (int i = 0; i < 3; ++i) {
    p.q_strides[i] = q.stride(i);
    p.k_strides[i] = k.stride(i);
    p.v_strides[i] = v.stride(i);
  }
  p.out_strides[0] = out.stride(0);
  p.out_strides[1] = out.stride(2);  // out is (B, N, H, d): heads are its dimension 2
  p.out_strides[2] = out.stride(1);
  p.scale = static_cast<float>(1.0 / std::sqrt(static_cast<double>(d)));
  if (!kernel(p, parallel_tasks))
    fail("fused CPU attention: out of memory for the packed keys and values of {} x {} heads of {} tokens", B, H,
         p.keys);
  return out.permute({0, 2, 1, 3});
}

}  // namespace cpu_kernels

std::optional<CpuIsa> fused_cpu_attention_isa(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v) {
  const std::optional<CpuIsa> isa = cpu_kernels::kernel_isa(q.scalar_type());
  if (!isa || !fused_cpu_refusal(q, k, v, *isa).empty()) return std::nullopt;
  return isa;
}

torch::Tensor fused_cpu_attention(const torch::Tensor& q_in, const torch::Tensor& k_in, const torch::Tensor& v_in,
                                  CpuIsa isa) {
  if (const std::string why = fused_cpu_refusal(q_in, k_in, v_in, isa); !why.empty())
    fail("fused CPU attention ({}): {}", cpu_isa_name(isa), why);
  const cpu_kernels::AttentionKernel kernel = isa == CpuIsa::Amx          ? cpu_kernels::attention_amx_bf16
                                              : isa == CpuIsa::Avx512Bf16 ? cpu_kernels::attention_avx512_bf16
                                              : isa == CpuIsa::Avx512     ? cpu_kernels::attention_avx512_fp32
                                                                          : cpu_kernels::attention_avx2_fp32;
  return cpu_kernels::run_attention_kernel(q_in, k_in, v_in, kernel);
}

torch::Tensor attention(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v, AttentionForm form) {
  if (form == AttentionForm::Full) return naive_attention(q, k, v);
  if (form == AttentionForm::Fastest) {
    if (compat::has_fused_sdpa && q.is_cuda()) return compat::fused_sdpa(q, k, v);
    if (const auto isa = fused_cpu_attention_isa(q, k, v)) return fused_cpu_attention(q, k, v, *isa);
  }
  return chunked_attention(q, k, v);
}

}  // namespace ii
