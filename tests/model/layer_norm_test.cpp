#include <gtest/gtest.h>

#include "common/cpu_features.h"
#include "model/layer_norm.h"

namespace ii {
namespace {
// A namespace of its own: the folder's test files are compiled together (CMake's unity build).
namespace layer_norm_test {

double max_abs(const torch::Tensor& a, const torch::Tensor& b) {
  return (a.to(torch::kFloat64) - b.to(torch::kFloat64)).abs().max().item<double>();
}

// The fused residual add + layer norm against LibTorch's operations: rows whose width is not
// a multiple of the vector width (8, 100, 1000) and the network's (192, 1024), with and without
// a residual. Values off-centre, as the residual stream is.
TEST(AddLayerNorm, Float32MatchesLibTorch) {
  torch::manual_seed(10);
  for (int64_t d : {8, 100, 192, 1000, 1024}) {
    const torch::Tensor x = torch::randn({2, 37, d}) * 3 + 1.5;
    const torch::Tensor residual = torch::randn({2, 37, d});
    for (bool with_residual : {false, true}) {
      const torch::Tensor r = with_residual ? residual : torch::Tensor();
      const AddNorm fused = add_layer_norm(x, r, 1e-6, torch::kFloat32);
      const AddNorm ref = add_layer_norm(x, r, 1e-6, torch::kFloat32, false);
      EXPECT_TRUE(torch::equal(fused.sum, ref.sum)) << d;
      EXPECT_LT(max_abs(fused.normed, ref.normed), 1e-5) << "width " << d << " residual " << with_residual;
    }
  }
}

// bf16: the sum is the same float addition; the normalised values differ from LibTorch's by
// float rounding before the conversion, so at most one bf16 step.
TEST(AddLayerNorm, BFloat16MatchesLibTorchWithinOneStep) {
  torch::manual_seed(11);
  for (int64_t d : {100, 1024}) {
    const torch::Tensor x = torch::randn({3, 50, d}) * 2;
    const torch::Tensor residual = torch::randn({3, 50, d}).to(torch::kBFloat16);
    const AddNorm fused = add_layer_norm(x, residual, 1e-6, torch::kBFloat16);
    const AddNorm ref = add_layer_norm(x, residual, 1e-6, torch::kBFloat16, false);
    ASSERT_EQ(fused.normed.scalar_type(), torch::kBFloat16);
    EXPECT_TRUE(torch::equal(fused.sum, ref.sum));
    const torch::Tensor a = fused.normed.to(torch::kFloat32), b = ref.normed.to(torch::kFloat32);
    EXPECT_TRUE(((a - b).abs() <= b.abs() / 128 + 1e-6).all().item<bool>()) << "width " << d;
  }
}

TEST(AddLayerNorm, GradientsUseLibTorch) {
  const torch::Tensor x = torch::randn({4, 16}, torch::requires_grad());
  const AddNorm r = add_layer_norm(x, torch::randn({4, 16}), 1e-6, torch::kFloat32);
  ASSERT_TRUE(r.normed.requires_grad());
  r.normed.pow(2).sum().backward();
  EXPECT_TRUE(x.grad().defined());
}

}  // namespace layer_norm_test
}  // namespace
}  // namespace ii
