#pragma once
// The step between two matrix products of a transformer block, fused on the CPU.
#include "common/torch.h"

namespace ii {

struct AddNorm {
  torch::Tensor sum;     // x + residual, float (x itself without a residual)
  torch::Tensor normed;  // layer_norm(sum) without affine parameters, in the compute dtype
};

// x: (..., D) float; residual: like x in `dtype`, or undefined. With `fused`, one pass per
// row with the CPU kernels (model/cpu) where they apply (CPU, contiguous inputs, a kernel set
// for `dtype`, no gradients wanted); LibTorch operations otherwise, which are the reference.
AddNorm add_layer_norm(const torch::Tensor& x, const torch::Tensor& residual, double eps, torch::ScalarType dtype,
                       bool fused = true);

}  // namespace ii
