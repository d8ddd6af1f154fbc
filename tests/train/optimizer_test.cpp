// AdamW against a hand computation, the official weight-decay rule, per-tensor clipping.
#include <gtest/gtest.h>

#include <cmath>

#include "train/optimizer.h"

namespace ii {
namespace {

TEST(AdamW, MatchesHandComputation) {
  torch::Tensor p = torch::tensor({1.0f, -2.0f}).set_requires_grad(true);
  torch::Tensor q = torch::tensor({0.5f}).set_requires_grad(true);
  AdamWOptions o;  // 0.9, 0.95, 1e-8, 0.05
  AdamW opt({p, q}, {true, false}, o);
  const double grads[2][2] = {{0.3, -0.1}, {-0.2, 0.4}};
  const double lrs[2] = {1e-2, 5e-3};
  double value[2] = {1.0, -2.0}, m[2] = {0, 0}, v[2] = {0, 0};
  double qv = 0.5, qm = 0, qs = 0;
  for (int t = 1; t <= 2; ++t) {
    p.mutable_grad() = torch::tensor({float(grads[t - 1][0]), float(grads[t - 1][1])});
    q.mutable_grad() = torch::tensor({float(grads[t - 1][0])});
    opt.step(lrs[t - 1]);
    const double lr = lrs[t - 1], b1 = 1 - std::pow(0.9, t), b2 = 1 - std::pow(0.95, t);
    for (int i = 0; i < 2; ++i) {
      const double g = grads[t - 1][i];
      value[i] *= 1 - lr * 0.05;
      m[i] = 0.9 * m[i] + 0.1 * g;
      v[i] = 0.95 * v[i] + 0.05 * g * g;
      value[i] -= lr / b1 * m[i] / (std::sqrt(v[i]) / std::sqrt(b2) + 1e-8);
    }
    const double g = grads[t - 1][0];  // q: no decay
    qm = 0.9 * qm + 0.1 * g;
    qs = 0.95 * qs + 0.05 * g * g;
    qv -= lr / b1 * qm / (std::sqrt(qs) / std::sqrt(b2) + 1e-8);
  }
  EXPECT_NEAR(p[0].item<double>(), value[0], 1e-6);
  EXPECT_NEAR(p[1].item<double>(), value[1], 1e-6);
  EXPECT_NEAR(q[0].item<double>(), qv, 1e-6);
  EXPECT_EQ(opt.steps(), 2);
}

TEST(AdamW, SkipsParametersWithoutGradient) {
  torch::Tensor p = torch::ones({2, 2}).set_requires_grad(true);
  AdamW opt({p}, {true});
  opt.step(0.1);
  EXPECT_TRUE(torch::equal(p, torch::ones({2, 2})));  // no decay either, like torch
}

TEST(AdamW, OfficialDecayRule) {
  EXPECT_TRUE(official_decays("gaudecoder.blocks.0.attn.qkv.weight_g", torch::zeros({8, 1})));
  EXPECT_TRUE(official_decays("mvencoder.cls_token", torch::zeros({1, 1, 8})));
  EXPECT_FALSE(official_decays("head.bias", torch::zeros({8, 2})));
  EXPECT_FALSE(official_decays("norm.weight", torch::zeros({8})));
}

TEST(ClipGradients, PerTensorWithNonFiniteZeroed) {
  torch::Tensor big = torch::zeros({2}).set_requires_grad(true);
  torch::Tensor small = torch::zeros({2}).set_requires_grad(true);
  torch::Tensor bad = torch::zeros({3}).set_requires_grad(true);
  torch::Tensor none = torch::zeros({1}).set_requires_grad(true);
  big.mutable_grad() = torch::tensor({3.0f, 4.0f});    // norm 5 -> scaled to norm 5/(5+1e-6)
  small.mutable_grad() = torch::tensor({0.3f, 0.4f});  // norm 0.5 -> kept
  bad.mutable_grad() = torch::tensor({NAN, INFINITY, 2.0f});
  const ClipStats s = clip_gradients_per_tensor({big, small, bad, none}, 1.0);
  EXPECT_NEAR(big.grad()[0].item<double>(), 3.0 / (5.0 + 1e-6), 1e-7);
  EXPECT_NEAR(big.grad()[1].item<double>(), 4.0 / (5.0 + 1e-6), 1e-7);
  EXPECT_FLOAT_EQ(small.grad()[0].item<float>(), 0.3f);
  // Non-finite values become 0; the rest (norm 2) is then clipped to norm 1.
  EXPECT_FLOAT_EQ(bad.grad()[0].item<float>(), 0.f);
  EXPECT_FLOAT_EQ(bad.grad()[1].item<float>(), 0.f);
  EXPECT_NEAR(bad.grad()[2].item<double>(), 2.0 / (2.0 + 1e-6), 1e-7);
  EXPECT_FALSE(none.grad().defined());
  EXPECT_EQ(s.clipped_tensors, 2);
  EXPECT_EQ(s.nonfinite_tensors, 1);
  EXPECT_NEAR(s.norm, std::sqrt(25.0 + 0.25 + 4.0), 1e-5);
}

}  // namespace
}  // namespace ii
