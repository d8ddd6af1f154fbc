#include <gtest/gtest.h>

#include "common/cpu_features.h"
#include "amx_tile_model.h"
#include "model/attention.h"
#include "model/cpu/dispatch.h"
#include "test_support.h"

namespace ii {
namespace {
// A namespace of its own: the folder's test files are compiled together (CMake's unity build).
namespace attention_test {

float max_abs(const torch::Tensor& a, const torch::Tensor& b) {
  return static_cast<float>((a.to(torch::kFloat64) - b.to(torch::kFloat64)).abs().max().item<double>());
}

// q, k, v as the network makes them: strided views of one (B, N, 3, heads, d) product.
struct Qkv {
  torch::Tensor q, k, v;
};
Qkv network_qkv(int64_t B, int64_t H, int64_t N, int64_t d, double spread, torch::ScalarType dtype) {
  const torch::Tensor qkv = (torch::randn({B, N, 3, H, d}) * spread).to(dtype).permute({2, 0, 3, 1, 4});
  return {qkv[0], qkv[1], qkv[2]};
}

std::vector<CpuIsa> float_kernels_here() {
  std::vector<CpuIsa> isas;
  for (CpuIsa isa : {CpuIsa::Avx2, CpuIsa::Avx512})
    if (cpu_features().has(isa)) isas.push_back(isa);
  return isas;
}

TEST(Attention, ChunkedEqualsTextbook) {
  torch::manual_seed(0);
  const auto q = torch::randn({2, 3, 50, 8}), k = torch::randn({2, 3, 50, 8}), v = torch::randn({2, 3, 50, 8});
  const auto ref = naive_attention(q, k, v);
  // A tiny chunk budget forces many chunks (one query row each).
  EXPECT_LT(max_abs(chunked_attention(q, k, v, 1), ref), 1e-5);
  EXPECT_LT(max_abs(attention(q, k, v), ref), 1e-5);
  EXPECT_LT(max_abs(attention(q, k, v, AttentionForm::Full), ref), 1e-5);
}

// bf16 inputs: the chunked form computes in float. LibTorch 1.13's CPU bf16 batched product sums
// in bf16, which over a few thousand keys lost most of the output (the default model's statue
// renders were 22 dB from float32's).
TEST(Attention, ChunkedBf16SumsInFloat) {
  torch::manual_seed(3);
  const auto q = torch::randn({1, 2, 64, 64}).to(torch::kBFloat16), k = torch::randn({1, 2, 3000, 64}).to(torch::kBFloat16),
             v = torch::randn({1, 2, 3000, 64}).to(torch::kBFloat16);
  const auto exact = naive_attention(q.to(torch::kFloat32), k.to(torch::kFloat32), v.to(torch::kFloat32));
  const auto chunked = chunked_attention(q, k, v);
  EXPECT_EQ(chunked.scalar_type(), torch::kBFloat16);
  // What remains is the output's rounding to bf16: 2^-9 of values up to ~0.5.
  EXPECT_LT(max_abs(chunked, exact), 2e-3);
}

TEST(Attention, ChunkedHasGradients) {
  torch::manual_seed(1);
  const auto q = torch::randn({1, 2, 9, 4}, torch::requires_grad()), k = torch::randn({1, 2, 9, 4}),
             v = torch::randn({1, 2, 9, 4});
  // With gradients wanted the fastest form is the chunked one (the fused kernel has no backward).
  EXPECT_FALSE(fused_cpu_attention_isa(q, k, v).has_value());
  attention(q, k, v).sum().backward();
  const auto q2 = q.detach().clone().requires_grad_(true);
  naive_attention(q2, k, v).sum().backward();
  EXPECT_LT(max_abs(q.grad(), q2.grad()), 1e-5);
}

// Float32: within 1e-5 of the chunked twin, for token counts that are not multiples of the
// kernels' blocks (1, odd, across key blocks of 256/512 and query tiles of 96), head
// dimensions 8 to 128 (the presets have 8, 48 and 64), batches, and strided inputs.
TEST(FusedCpuAttention, Float32MatchesChunkedTwin) {
  if (float_kernels_here().empty()) GTEST_SKIP() << "this CPU has no AVX2";
  torch::manual_seed(2);
  for (CpuIsa isa : float_kernels_here())
    for (int64_t d : {8, 32, 48, 64, 128})
      for (int64_t n : {1, 7, 49, 300, 517}) {
        const Qkv t = network_qkv(2, 3, n, d, 1.0, torch::kFloat32);
        const torch::Tensor fused = fused_cpu_attention(t.q, t.k, t.v, isa);
        ASSERT_EQ(fused.sizes(), t.q.sizes());
        EXPECT_LT(max_abs(fused, chunked_attention(t.q, t.k, t.v)), 1e-5)
            << cpu_isa_name(isa) << " head_dim " << d << " tokens " << n;
      }
}

TEST(FusedCpuAttention, KeysMayOutnumberQueries) {
  if (float_kernels_here().empty()) GTEST_SKIP() << "this CPU has no AVX2";
  torch::manual_seed(3);
  const auto q = torch::randn({1, 2, 5, 64}), k = torch::randn({1, 2, 333, 64}), v = torch::randn({1, 2, 333, 64});
  for (CpuIsa isa : float_kernels_here())
    EXPECT_LT(max_abs(fused_cpu_attention(q, k, v, isa), naive_attention(q, k, v)), 1e-5) << cpu_isa_name(isa);
}

// Scores in the hundreds: the running maximum must keep every exponent in range, and the
// result stays as close to float64 attention as the chunked twin is.
TEST(FusedCpuAttention, PeakedScoresStayAccurate) {
  if (float_kernels_here().empty()) GTEST_SKIP() << "this CPU has no AVX2";
  torch::manual_seed(4);
  const Qkv t = network_qkv(1, 2, 300, 64, 12.0, torch::kFloat32);
  const torch::Tensor exact =
      naive_attention(t.q.to(torch::kFloat64), t.k.to(torch::kFloat64), t.v.to(torch::kFloat64));
  const float chunked_error = max_abs(chunked_attention(t.q, t.k, t.v), exact);
  for (CpuIsa isa : float_kernels_here()) {
    const torch::Tensor fused = fused_cpu_attention(t.q, t.k, t.v, isa);
    EXPECT_TRUE(torch::isfinite(fused).all().item<bool>()) << cpu_isa_name(isa);
    EXPECT_LT(max_abs(fused, exact), 2 * chunked_error + 1e-6) << cpu_isa_name(isa);
  }
}

// bf16: against float32 attention of the same bf16 values, no further from it than the
// chunked bf16 form (whose probabilities and products are bf16 too), plus one bf16 step.
TEST(FusedCpuAttention, BFloat16IsAsCloseToFloat32AsTheChunkedForm) {
  if (!cpu_features().has(CpuIsa::Avx512Bf16)) GTEST_SKIP() << "this CPU has no AVX-512 BF16";
  std::vector<CpuIsa> kernels = {CpuIsa::Avx512Bf16};
  if (cpu_features().has(CpuIsa::Amx)) kernels.push_back(CpuIsa::Amx);
  torch::manual_seed(5);
  for (int64_t d : {8, 32, 64, 128})
    for (int64_t n : {1, 7, 300, 517, 1100}) {
      const Qkv t = network_qkv(2, 3, n, d, 1.5, torch::kBFloat16);
      const torch::Tensor exact = chunked_attention(t.q.to(torch::kFloat32), t.k.to(torch::kFloat32),
                                                    t.v.to(torch::kFloat32));
      const float chunked_error = max_abs(chunked_attention(t.q, t.k, t.v), exact);
      for (CpuIsa isa : kernels) {
        const torch::Tensor fused = fused_cpu_attention(t.q, t.k, t.v, isa);
        ASSERT_EQ(fused.scalar_type(), torch::kBFloat16);
        EXPECT_LT(max_abs(fused, exact), chunked_error + 8e-3)
            << cpu_isa_name(isa) << ": head_dim " << d << " tokens " << n;
      }
    }
}

// The AMX kernel's packing, tiling and online softmax, on a model of the tiles (any CPU with
// AVX2): within one bf16 step of the chunked bf16 form's error, across head sizes that pad to
// whole tiles, queries past one task (64), keys past one block (512) and padded to whole tiles. (Where the CPU has AMX,
// BFloat16IsAsCloseToFloat32AsTheChunkedForm runs the hardware's.)
TEST(FusedCpuAttention, TheAmxKernelOnAModelOfTheTilesIsAsCloseAsTheChunkedForm) {
  if (!cpu_features().has(CpuIsa::Avx2)) GTEST_SKIP() << "this CPU has no AVX2 (the model is compiled for it)";
  torch::manual_seed(6);
  for (int64_t d : {8, 40, 64, 128})
    for (int64_t n : {1, 7, 65, 600}) {
      const Qkv t = network_qkv(2, 3, n, d, 1.5, torch::kBFloat16);
      const torch::Tensor exact = chunked_attention(t.q.to(torch::kFloat32), t.k.to(torch::kFloat32),
                                                    t.v.to(torch::kFloat32));
      const float chunked_error = max_abs(chunked_attention(t.q, t.k, t.v), exact);
      const torch::Tensor modelled =
          cpu_kernels::run_attention_kernel(t.q, t.k, t.v, test::attention_amx_bf16_on_tile_model);
      ASSERT_EQ(modelled.scalar_type(), torch::kBFloat16);
      EXPECT_EQ(test::tile_model_unconfigured_uses(), 0);
      EXPECT_LT(max_abs(modelled, exact), chunked_error + 8e-3) << "head_dim " << d << " tokens " << n;
    }
}

// The AMX kernel where the CPU has it, else the AVX-512 BF16 one: what the network runs.
TEST(FusedCpuAttention, BFloat16UsesTheBestKernelOfThisCpu) {
  if (!cpu_features().has(CpuIsa::Avx512Bf16)) GTEST_SKIP() << "this CPU has no AVX-512 BF16";
  const auto x = torch::randn({1, 2, 10, 64}).to(torch::kBFloat16);
  EXPECT_EQ(fused_cpu_attention_isa(x, x, x), cpu_features().isa);
}

TEST(FusedCpuAttention, FastestFormUsesItWithoutGradients) {
  const auto x = torch::randn({1, 2, 10, 64});
  const std::optional<CpuIsa> isa = fused_cpu_attention_isa(x, x, x);
  if (!cpu_features().has(CpuIsa::Avx2)) {
    EXPECT_FALSE(isa.has_value());
    return;
  }
  ASSERT_TRUE(isa.has_value());
  EXPECT_EQ(*isa, cpu_features().has(CpuIsa::Avx512) ? CpuIsa::Avx512 : CpuIsa::Avx2);
  // The result is a view whose heads are already interleaved per token: merging them is free.
  const torch::Tensor merged = attention(x, x, x).permute({0, 2, 1, 3});
  EXPECT_TRUE(merged.is_contiguous());
  EXPECT_FALSE(fused_cpu_attention_isa(x.to(torch::kFloat64), x.to(torch::kFloat64), x.to(torch::kFloat64)));
  EXPECT_FALSE(fused_cpu_attention_isa(torch::randn({1, 1, 4, 200}), torch::randn({1, 1, 4, 200}),
                                       torch::randn({1, 1, 4, 200})));
}

TEST(FusedCpuAttention, RefusesWhatItCannotRun) {
  if (!cpu_features().has(CpuIsa::Avx2)) GTEST_SKIP() << "this CPU has no AVX2";
  const auto x = torch::randn({1, 2, 10, 64});
  EXPECT_EQ(test::error_message([&] {
              const auto d = x.to(torch::kFloat64);
              fused_cpu_attention(d, d, d, CpuIsa::Avx2);
            }),
            "fused CPU attention (avx2): no avx2 kernel for Double");
  EXPECT_EQ(test::error_message([&] {
              const auto y = torch::randn({1, 1, 4, 200});
              fused_cpu_attention(y, y, y, CpuIsa::Avx2);
            }),
            "fused CPU attention (avx2): head_dim 200 is over 128");
  EXPECT_EQ(test::error_message([&] {
              const auto g = x.clone().requires_grad_(true);
              fused_cpu_attention(g, x, x, CpuIsa::Avx2);
            }),
            "fused CPU attention (avx2): gradients are wanted (the kernel has no backward pass)");
  EXPECT_EQ(test::error_message([&] { fused_cpu_attention(x, x.narrow(2, 0, 5), x, CpuIsa::Avx2); }),
            "fused CPU attention (avx2): q, k and v shapes do not match");
}

TEST(CpuFeatures, LevelNames) {
  EXPECT_EQ(parse_cpu_isa("avx2", "X"), CpuIsa::Avx2);
  EXPECT_EQ(parse_cpu_isa("avx512_bf16", "X"), CpuIsa::Avx512Bf16);
  EXPECT_EQ(parse_cpu_isa("amx", "X"), CpuIsa::Amx);
  EXPECT_EQ(test::error_message([] { parse_cpu_isa("sse9", "INSTAINPAINT_MAX_CPU_ISA"); }),
            "INSTAINPAINT_MAX_CPU_ISA: unknown instruction set 'sse9' (expected baseline, avx2, avx512, "
            "avx512_bf16 or amx)");
}

}  // namespace attention_test
}  // namespace
}  // namespace ii
