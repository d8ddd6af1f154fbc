#include <gtest/gtest.h>

#include "model/checkpoint.h"
#include "model/network.h"
#include "test_support.h"

namespace ii {
namespace {

TEST(Unpatchify, FollowsOfficialLayout) {
  const int V = 2, h = 2, w = 3, p = 2, C = 3;
  const torch::Tensor x = torch::arange(V * h * w * p * p * C, torch::kFloat32).reshape({1, V * h * w, p * p * C});
  const torch::Tensor y = unpatchify(x, V, h, w, p, C);
  ASSERT_EQ(y.sizes(), (std::vector<int64_t>{1, V, C, h * p, w * p}));
  // Element (py*p + px)*C + c of token v*h*w + a*w + b is channel c of pixel (a*p+py, b*p+px).
  for (int v = 0; v < V; ++v)
    for (int a = 0; a < h; ++a)
      for (int b = 0; b < w; ++b)
        for (int py = 0; py < p; ++py)
          for (int px = 0; px < p; ++px)
            for (int c = 0; c < C; ++c)
              EXPECT_EQ(y[0][v][c][a * p + py][b * p + px].item<float>(),
                        x[0][v * h * w + a * w + b][(py * p + px) * C + c].item<float>());
}

TEST(ModelConfig, PresetSizes) {
  // Release: 308,902,656 parameters in the official layout, of which 24*9216 + 5*(1024 +
  // out) are weight-norm gains that fold away.
  const ModelConfig release = ModelConfig::from_preset("release");
  EXPECT_EQ(release.parameter_count(), 308902656 - 24 * 9216 - (5 * 1024 + 64 + 192 + 64 + 192 + 256));
  EXPECT_EQ(test::error_message([] { ModelConfig::from_preset("huge"); }),
            "unknown model preset 'huge' (known: release, base, small, medium, mini, tiny)");
  ModelConfig bad = release;
  bad.heads = 5;
  EXPECT_EQ(test::error_message([&] { bad.validate(); }), "model config: embed_dim 1024 is not divisible by 5 heads");
  EXPECT_EQ(test::error_message([] { ModelConfig::from_json({{"rgb_from_input", "yes"}}); }),
            "model config: rgb_from_input has the wrong type (\"yes\")");
  EXPECT_TRUE(ModelConfig::from_json({{"rgb_from_input", true}}).rgb_from_input);
}

TEST(Checkpoint, SafetensorsRoundTripKeepsWeightsAndArchitecture) {
  torch::manual_seed(1);
  ModelConfig c = ModelConfig::from_preset("tiny");
  c.heads = 4;
  const Network net(c);
  const auto path = test::temp_dir("ckpt") / "m.safetensors";
  save_safetensors_checkpoint(path, net);
  const Checkpoint back = read_checkpoint(path);
  EXPECT_EQ(back.format, "safetensors");
  EXPECT_EQ(back.config.heads, 4);
  EXPECT_EQ(back.config.blocks, 2);
  for (const auto& [name, w] : net.named_parameters()) {
    ASSERT_TRUE(back.state.count(name)) << name;
    EXPECT_LT((back.state.at(name) - w).abs().max().item<float>(), 1e-6) << name;
  }
  // Official key names on disk: weight-normed layers as weight_g / weight_v.
  const StateDict raw = read_safetensors_tensors(path);
  EXPECT_TRUE(raw.count("gaudecoder.blocks.0.attn.qkv.weight_g"));
  EXPECT_TRUE(raw.count("gauupsampler.mlp_rgb.2.weight_v"));
  EXPECT_TRUE(raw.count("mvencoder.patch_embed.proj.weight"));
  // Read in place from the mapped file (a GPU's predictor): the same weights and architecture.
  const Checkpoint mapped = read_checkpoint(path, false, /*map_weights=*/true);
  EXPECT_EQ(mapped.config.heads, 4);
  EXPECT_EQ(mapped.folded_weight_norms, back.folded_weight_norms);
  ASSERT_EQ(mapped.state.size(), back.state.size());
  for (const auto& [name, w] : back.state) EXPECT_TRUE(torch::equal(mapped.state.at(name), w)) << name;
}

TEST(Checkpoint, StrictLoadNamesWhatDoesNotFit) {
  Network net(ModelConfig::from_preset("tiny"));
  StateDict state;
  for (const auto& [name, w] : net.named_parameters()) state[name] = w.clone();
  state.erase("gaudecoder.blocks.1.mlp.fc2.weight");
  state["mvencoder.patch_embed.proj.weight"] = torch::zeros({128, 3, 8, 8});
  state["gaudecoder.norm.weight"] = torch::zeros({128});
  EXPECT_EQ(test::error_message([&] { net.load(state, "x.pth"); }),
            "x.pth: checkpoint does not fit the model architecture\n"
            "  wrong shape (1): mvencoder.patch_embed.proj.weight has shape [128, 3, 8, 8], the tiny model needs [128, 4, 8, 8]\n"
            "  missing (1): gaudecoder.blocks.1.mlp.fc2.weight\n"
            "  unexpected (1): gaudecoder.norm.weight");
}

TEST(Checkpoint, WeightNormFoldsAndModulePrefixIsStripped) {
  StateDict raw;
  raw["gaudecoder.module.blocks.0.attn.proj.weight_g"] = torch::tensor({{2.0f}, {3.0f}});
  raw["gaudecoder.module.blocks.0.attn.proj.weight_v"] = torch::tensor({{3.0f, 4.0f}, {0.0f, 1.0f}});
  raw["optimizer.state.0.exp_avg"] = torch::zeros({2});
  int folded = 0;
  const StateDict s = normalize_state_dict(raw, &folded);
  EXPECT_EQ(folded, 1);
  ASSERT_EQ(s.size(), 1u);
  const auto w = s.at("gaudecoder.blocks.0.attn.proj.weight");
  EXPECT_TRUE(torch::allclose(w, torch::tensor({{1.2f, 1.6f}, {0.0f, 3.0f}})));
  raw.erase("gaudecoder.module.blocks.0.attn.proj.weight_v");
  EXPECT_EQ(test::error_message([&] { normalize_state_dict(raw); }),
            "weight-norm gain gaudecoder.blocks.0.attn.proj.weight_g has no matching "
            "gaudecoder.blocks.0.attn.proj.weight_v");
}

TEST(Network, RgbFromInputAddsTheHeadToTheInputColour) {
  torch::manual_seed(5);
  ModelConfig c = ModelConfig::from_preset("tiny");
  c.rgb_from_input = true;
  Network net(c);
  const torch::Tensor images = torch::rand({1, 2, 4, 16, 16}) * 2 - 1;
  const torch::Tensor plucker = torch::randn({1, 2, 6, 16, 16});
  const torch::Tensor rays = torch::randn({1, 2, 16, 16, 3});
  const torch::Tensor with_skip = net.forward(images, plucker, rays, rays).gaussians.rgb;
  c.rgb_from_input = false;
  Network plain(c, false);
  std::map<std::string, torch::Tensor> state(net.named_parameters().begin(), net.named_parameters().end());
  plain.load(state, "test");
  const torch::Tensor head_only = plain.forward(images, plucker, rays, rays).gaussians.rgb;
  // Input RGB in [-1,1] becomes a colour in [0,1].
  const torch::Tensor expected = head_only + (images.slice(2, 0, 3) + 1) / 2;
  EXPECT_LT((with_skip - expected).abs().max().item<float>(), 1e-6);
}

// A model whose sizes are those of 8-row pictures, run at 16 rows: every Gaussian half as large
// as in scene units, everything else alike; at 16 rows or fewer (a reference of 16 or 32) as in
// scene units; the setting travels with the config.
TEST(Network, ScaleReferenceHeightKeepsTheGaussiansWidthInPixels) {
  torch::manual_seed(6);
  ModelConfig c = ModelConfig::from_preset("tiny");
  Network in_scene_units(c);
  const torch::Tensor images = torch::rand({1, 2, 4, 16, 16}) * 2 - 1;
  const torch::Tensor plucker = torch::randn({1, 2, 6, 16, 16});
  const torch::Tensor rays = torch::randn({1, 2, 16, 16, 3});
  const GaussianMaps plain = in_scene_units.forward(images, plucker, rays, rays).gaussians;
  const std::map<std::string, torch::Tensor> state(in_scene_units.named_parameters().begin(),
                                                   in_scene_units.named_parameters().end());
  auto run_with_reference = [&](int reference) {
    c.scale_reference_height = reference;
    Network in_pixels(c, false);
    in_pixels.load(state, "test");
    return in_pixels.forward(images, plucker, rays, rays).gaussians;
  };
  const GaussianMaps scaled = run_with_reference(8);
  EXPECT_TRUE(torch::allclose(scaled.scale, plain.scale * 0.5, 1e-6, 0));
  EXPECT_TRUE(torch::equal(scaled.xyz, plain.xyz));
  EXPECT_TRUE(torch::equal(scaled.opacity, plain.opacity));
  EXPECT_TRUE(torch::equal(run_with_reference(16).scale, plain.scale));
  EXPECT_TRUE(torch::equal(run_with_reference(32).scale, plain.scale));
  c.scale_reference_height = 128;
  EXPECT_EQ(ModelConfig::from_json(c.to_json()).scale_reference_height, 128);
  EXPECT_EQ(ModelConfig::from_preset("mini").scale_reference_height, 128);
  EXPECT_EQ(ModelConfig::from_preset("release").scale_reference_height, 0) << "the official model's sizes are in scene units";
  c.scale_reference_height = -1;
  EXPECT_EQ(test::error_message([&] { c.validate(); }),
            "model config: scale_reference_height must be 0 (sizes in scene units) or a height in pixels, got -1");
}

// The heads' first Linears run as one product over a concatenation kept between inference
// calls; loading other weights must not leave the old concatenation (or its bf16 copy) behind.
TEST(Network, FusedHeadsFollowEveryLoad) {
  const ModelConfig c = ModelConfig::from_preset("tiny");
  torch::manual_seed(6);
  Network first(c), second(c);
  const torch::Tensor images = torch::rand({1, 2, 4, 16, 16}) * 2 - 1;
  const torch::Tensor plucker = torch::randn({1, 2, 6, 16, 16});
  const torch::Tensor rays = torch::randn({1, 2, 16, 16, 3});
  torch::NoGradGuard no_grad;
  for (Precision precision : {Precision::Float32, Precision::BFloat16}) {
    Network net = first;
    net.forward(images, plucker, rays, rays, precision);  // builds the caches from `first`
    std::map<std::string, torch::Tensor> state(second.named_parameters().begin(), second.named_parameters().end());
    net.load(state, "test");
    const GaussianMaps got = net.forward(images, plucker, rays, rays, precision).gaussians;
    const GaussianMaps expected = second.forward(images, plucker, rays, rays, precision).gaussians;
    EXPECT_TRUE(torch::equal(got.opacity, expected.opacity)) << precision_name(precision);
    EXPECT_TRUE(torch::equal(got.rotation, expected.rotation)) << precision_name(precision);
  }
  // One head by hand (float32): opacity = sigmoid(W2 gelu(W1 LN(tokens)) + bias), unpatchified.
  const NetworkOutput out = second.forward(images, plucker, rays, rays);
  std::map<std::string, torch::Tensor> w(second.named_parameters().begin(), second.named_parameters().end());
  const torch::Tensor normed = torch::layer_norm(out.transformer_tokens, {c.embed_dim}, {}, {}, c.ln_eps);
  const torch::Tensor hidden = torch::gelu(torch::matmul(normed, w.at("gauupsampler.mlp_opacity.0.weight").t()));
  const torch::Tensor raw = torch::matmul(hidden, w.at("gauupsampler.mlp_opacity.2.weight").t());
  const int h = 16 / c.patch;
  const torch::Tensor opacity = torch::sigmoid(unpatchify(raw, 2, h, h, c.patch, 1) + c.opacity_bias);
  EXPECT_LT((opacity - out.gaussians.opacity).abs().max().item<float>(), 1e-6);
}

}  // namespace
}  // namespace ii
