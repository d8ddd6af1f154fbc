// FP8 attention: the E4M3 rounding against an independent decoder of the format's bits (and,
// in LibTorch 2.x, against its float8_e4m3fn cast), the emulated attention's error, and on a
// Hopper GPU cuDNN's kernel against float32 beside the emulation (the official fixture with
// FP8 attention: ModelParity.Fp8AttentionStaysNearFloat32).
#include <gtest/gtest.h>

#include <cmath>

#include "common/torch_compat.h"
#include "model/attention.h"
#include "model/fp8_attention.h"
#include "test_support.h"

namespace ii {
namespace {

// The value of an E4M3 (fn) byte from its bits: sign, 4 exponent bits with bias 7, 3 mantissa
// bits; exponent 0 is subnormal; S.1111.111 is NaN (no infinities).
double e4m3_value(int bits) {
  const int sign = bits >> 7 & 1, exponent = bits >> 3 & 15, mantissa = bits & 7;
  const double magnitude =
      exponent == 0 ? std::ldexp(mantissa / 8.0, -6) : std::ldexp(1.0 + mantissa / 8.0, exponent - 7);
  return sign ? -magnitude : magnitude;
}

std::vector<float> finite_e4m3_values() {
  std::vector<float> values;
  for (int bits = 0; bits < 256; ++bits)
    if ((bits & 0x7f) != 0x7f) values.push_back(static_cast<float>(e4m3_value(bits)));
  return values;
}

float max_abs(const torch::Tensor& a, const torch::Tensor& b) {
  return (a.to(torch::kFloat32) - b.to(torch::kFloat32)).abs().max().item<float>();
}

TEST(Fp8, EveryE4m3ValueIsKeptAndTheLargestIs448) {
  const std::vector<float> values = finite_e4m3_values();
  const torch::Tensor t = torch::tensor(values);
  EXPECT_EQ(max_abs(round_to_e4m3(t), t), 0.0f);
  EXPECT_EQ(t.abs().max().item<float>(), kE4m3Max);
}

TEST(Fp8, ValuesBetweenRoundToTheNearestTiesToEven) {
  // 1 + 1/16 lies halfway between 1 and 1.125 (mantissa 000 and 001): ties go to the even 1.
  // 1.125 + 1/16 lies between 1.125 (001) and 1.25 (010): it goes to 1.25.
  const torch::Tensor in = torch::tensor({1.0625f, 1.1875f, 1.07f, -3.3f, 0.1f, 1000.0f, -500.0f, 0.001f, 0.0f});
  const torch::Tensor want = torch::tensor({1.0f, 1.25f, 1.125f, -3.25f, 0.1015625f, 448.0f, -448.0f,
                                            std::ldexp(1.0f, -9), 0.0f});  // 0.001 is nearest 2^-9
  EXPECT_EQ(max_abs(round_to_e4m3(in), want), 0.0f);
}

TEST(Fp8, RoundingIsTheNearestOfTheFormatsValues) {
  // Against a search over the decoded values: the distance to the rounding is the least.
  torch::manual_seed(5);
  const torch::Tensor x = torch::randn({4000}) * torch::exp(torch::randn({4000}) * 3);  // 2^-17 .. 2^17
  const torch::Tensor grid = torch::tensor(finite_e4m3_values());
  const torch::Tensor nearest_distance = std::get<0>((x.clamp(-kE4m3Max, kE4m3Max).unsqueeze(1) - grid).abs().min(1));
  EXPECT_EQ(max_abs((round_to_e4m3(x) - x.clamp(-kE4m3Max, kE4m3Max)).abs(), nearest_distance), 0.0f);
#if II_TORCH2
  // LibTorch 2.x's own cast, within the finite range.
  const torch::Tensor in_range = x.clamp(-kE4m3Max, kE4m3Max);
  EXPECT_EQ(max_abs(round_to_e4m3(in_range), in_range.to(at::kFloat8_e4m3fn).to(torch::kFloat32)), 0.0f);
#endif
}

TEST(Fp8, EmulatedAttentionIsWithinFp8sErrorOfFloat32) {
  torch::manual_seed(6);
  const torch::Tensor q = torch::randn({2, 3, 200, 64}), k = torch::randn({2, 3, 200, 64}),
                      v = torch::randn({2, 3, 200, 64});
  const torch::Tensor exact = naive_attention(q, k, v), fp8 = fp8_emulated_attention(q, k, v);
  const float largest = v.abs().max().item<float>();
  // Outputs are rounded to E4M3 in units of max|v|/448: at most 1/16 relative, plus the inputs' rounding.
  EXPECT_LT(max_abs(fp8, exact), 0.05f * largest);
  EXPECT_GT(max_abs(fp8, exact), 1e-4f);  // it really rounded
  // The query blocks do not change the result.
  EXPECT_EQ(max_abs(fp8_emulated_attention(q, k, v, 1), fp8), 0.0f);
  // The network's form, on a device without cuDNN's kernel, is the emulation.
  EXPECT_EQ(max_abs(attention(q, k, v, AttentionForm::Fp8), fp8), 0.0f);
}

TEST(Fp8Cuda, CudnnKernelIsAsAccurateAsTheEmulation) {
  if (!torch::cuda::is_available()) GTEST_SKIP() << "no CUDA device";
  const torch::Device gpu(torch::kCUDA, 0);
  torch::manual_seed(7);
  // q, k, v as the network makes them: strided views of one (B, N, 3, heads, d) product.
  const torch::Tensor qkv = torch::randn({2, 1000, 3, 4, 64}).to(gpu, torch::kBFloat16).permute({2, 0, 3, 1, 4});
  const torch::Tensor q = qkv[0], k = qkv[1], v = qkv[2];
  if (const std::string why = cudnn_fp8_attention_refusal(q, k, v); !why.empty()) GTEST_SKIP() << why;
  torch::InferenceMode inference;
  const torch::Tensor kernel = cudnn_fp8_attention(q, k, v), emulated = fp8_emulated_attention(q, k, v);
  ASSERT_EQ(kernel.sizes(), q.sizes());
  const auto f32 = [](const torch::Tensor& t) { return t.to(torch::kFloat32); };
  const torch::Tensor exact = chunked_attention(f32(q), f32(k), f32(v));
  auto mean_error = [&](const torch::Tensor& t) { return (f32(t) - exact).abs().mean().item<float>(); };
  // The kernel rounds its probabilities against a running row maximum (flash attention), the
  // emulation against the final one: other roundings, the same precision. A wrong scale would
  // be far off both.
  std::printf("mean difference from float32: cuDNN FP8 %.5f, emulated FP8 %.5f\n", mean_error(kernel),
              mean_error(emulated));
  EXPECT_LT(mean_error(kernel), 1.5f * mean_error(emulated));
  EXPECT_LT(max_abs(kernel, exact), 2.0f * max_abs(emulated, exact));
  // The network's form takes the kernel here.
  EXPECT_EQ(max_abs(attention(q, k, v, AttentionForm::Fp8), kernel), 0.0f);
}

}  // namespace
}  // namespace ii
