#include "model/layer_norm.h"

#include "model/cpu/dispatch.h"

namespace ii {

namespace {

bool fused_applies(const torch::Tensor& x, const torch::Tensor& residual, torch::ScalarType dtype) {
  const bool grads = torch::GradMode::is_enabled() &&
                     (x.requires_grad() || (residual.defined() && residual.requires_grad()));
  if (grads || !x.device().is_cpu() || x.scalar_type() != torch::kFloat32 || !x.is_contiguous() || x.dim() == 0)
    return false;
  if (residual.defined() &&
      (residual.sizes() != x.sizes() || residual.scalar_type() != dtype || !residual.is_contiguous() ||
       !residual.device().is_cpu()))
    return false;
  return cpu_kernels::kernel_isa(dtype).has_value();
}

}  // namespace

AddNorm add_layer_norm(const torch::Tensor& x, const torch::Tensor& residual, double eps, torch::ScalarType dtype,
                       bool fused) {
  const int64_t D = x.size(-1);
  if (!fused || !fused_applies(x, residual, dtype)) {
    AddNorm r;
    r.sum = residual.defined() ? x + residual.to(torch::kFloat32) : x;
    r.normed = torch::layer_norm(r.sum, {D}, {}, {}, eps).to(dtype);
    return r;
  }
  AddNorm r;
  r.sum = residual.defined() ? torch::empty_like(x) : x;
  r.normed = torch::empty(x.sizes(), x.options().dtype(dtype));
  cpu_kernels::AddNormProblem p;
  p.rows = x.numel() / std::max<int64_t>(D, 1);
  p.dim = D;
  p.x = x.data_ptr<float>();
  p.residual = residual.defined() ? residual.data_ptr() : nullptr;
  p.sum = residual.defined() ? r.sum.data_ptr<float>() : nullptr;
  p.normed = r.normed.data_ptr();
  p.eps = static_cast<float>(eps);
  switch (*cpu_kernels::kernel_isa(dtype)) {
    case CpuIsa::Amx:  // no matrix product here: AVX-512 BF16's
    case CpuIsa::Avx512Bf16: cpu_kernels::add_layer_norm_avx512_bf16(p, cpu_kernels::parallel_tasks); break;
    case CpuIsa::Avx512: cpu_kernels::add_layer_norm_avx512_fp32(p, cpu_kernels::parallel_tasks); break;
    default: cpu_kernels::add_layer_norm_avx2_fp32(p, cpu_kernels::parallel_tasks); break;
  }
  return r;
}

}  // namespace ii
