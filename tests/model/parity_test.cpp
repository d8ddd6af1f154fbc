// Parity with the official implementation on the official-tiny fixture: the same weights,
// read from the official .pth container and from safetensors, give the official encoder
// tokens, transformer tokens and every Gaussian attribute within 1e-4 (float32; depth and
// positions relative to their magnitude).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <tuple>

#include <nlohmann/json.hpp>

#include "common/files.h"
#include "model/checkpoint.h"
#include "model/model_input.h"
#include "model/network.h"
#include "test_support.h"

namespace ii {
namespace {
// A namespace of its own: the folder's test files are compiled together (CMake's unity build).
namespace parity_test {

float max_abs(const torch::Tensor& a, const torch::Tensor& b) {
  EXPECT_EQ(a.sizes(), b.sizes());
  return (a - b).abs().max().item<float>();
}

// The largest difference relative to the reference's largest magnitude (at least 1): depth
// and positions are in scene units, where float32's last bits are worth more. The AVX-512
// kernels' 16-lane sums round differently from AVX2's 8 lanes (1.1e-4 absolute on depths).
float max_scaled(const torch::Tensor& a, const torch::Tensor& reference) {
  return max_abs(a, reference) / std::max(1.0f, reference.abs().max().item<float>());
}

void check_parity(const std::filesystem::path& checkpoint, const std::filesystem::path& io_path) {
  const StateDict io = read_safetensors_tensors(io_path);
  Network net = load_network(checkpoint);
  EXPECT_EQ(net.config().preset, "tiny");
  torch::NoGradGuard no_grad;
  const torch::Tensor images = io.at("encoder_input").unsqueeze(0);  // (1, 4, 4, 32, 48)
  const torch::Tensor plucker = io.at("plucker").unsqueeze(0);
  const NetworkOutput out = net.forward(images, plucker, io.at("rays_o"), io.at("rays_d_un"));

  const torch::Tensor expected_enc = io.at("tokens_encoder").narrow(1, 1, 24);  // drop cls
  EXPECT_LT(max_abs(out.encoder_tokens, expected_enc), 1e-4);
  EXPECT_LT(max_abs(out.transformer_tokens, io.at("tokens_transformer")), 1e-4);
  const GaussianMaps& g = out.gaussians;
  EXPECT_LT(max_scaled(g.depth, io.at("gs_depth")), 1e-4);
  EXPECT_LT(max_abs(g.rgb, io.at("gs_rgb")), 1e-4);
  EXPECT_LT(max_abs(g.opacity, io.at("gs_opacity")), 1e-4);
  EXPECT_LT(max_abs(g.scale, io.at("gs_scale")), 1e-4);
  EXPECT_LT(max_abs(g.rotation, io.at("gs_rotation")), 1e-4);
  EXPECT_LT(max_scaled(g.xyz, io.at("gs_xyz")), 1e-4);
}

TEST(ModelParity, OfficialPthCheckpoint) {
  II_REQUIRE_SHARED(ckpt, "fixtures/official-tiny/checkpoint.pth");
  check_parity(ckpt, test::shared_path("fixtures/official-tiny/io.safetensors"));
}

TEST(ModelParity, OfficialSafetensorsWeights) {
  II_REQUIRE_SHARED(ckpt, "fixtures/official-tiny/weights.safetensors");
  check_parity(ckpt, test::shared_path("fixtures/official-tiny/io.safetensors"));
}

TEST(ModelParity, InputTensorsMatchOfficialEncoderInput) {
  II_REQUIRE_SHARED(io_path, "fixtures/official-tiny/io.safetensors");
  const StateDict io = read_safetensors_tensors(io_path);
  // Rebuild the encoder input from the fixture's images, masks and cameras with our code.
  std::vector<PreparedView> views;
  const torch::Tensor rgb = io.at("rgb")[0], mask = io.at("mask")[0], cams = io.at("cameras")[0];
  for (int v = 0; v < 4; ++v) {
    PreparedView pv;
    pv.name = "v" + std::to_string(v);
    const torch::Tensor img = ((rgb[v] + 1.0) * 0.5).permute({1, 2, 0}).contiguous();
    pv.rgb = Image(48, 32, 3);
    std::memcpy(pv.rgb.pixels.data(), img.data_ptr<float>(), pv.rgb.pixels.size() * 4);
    pv.mask = Image(48, 32, 1);
    std::memcpy(pv.mask->pixels.data(), mask[v].contiguous().data_ptr<float>(), pv.mask->pixels.size() * 4);
    const float* c = cams[v].data_ptr<float>();
    for (int r = 0; r < 4; ++r)
      for (int k = 0; k < 4; ++k) pv.camera.c2w(r, k) = c[r * 4 + k];
    pv.camera.K = Intrinsics::from_fov(48, 32, c[16], c[17]);
    views.push_back(pv);
  }
  const ModelInput in = build_model_input(views, PoseNormalization{});  // already normalised
  EXPECT_LT(max_abs(in.images, io.at("encoder_input")), 1e-5);
  EXPECT_LT(max_abs(in.plucker, io.at("plucker")), 1e-5);
  EXPECT_LT(max_abs(in.cameras, cams), 1e-6);
}

// The official-tiny fixture's Gaussians in each precision, from the same weights and inputs.
std::vector<GaussianMaps> fixture_gaussians(const std::filesystem::path& checkpoint,
                                            const std::vector<Precision>& precisions) {
  const StateDict io = read_safetensors_tensors(test::shared_path("fixtures/official-tiny/io.safetensors"));
  Network net = load_network(checkpoint);
  torch::NoGradGuard no_grad;
  const torch::Tensor images = io.at("encoder_input").unsqueeze(0), plucker = io.at("plucker").unsqueeze(0);
  std::vector<GaussianMaps> out;
  for (Precision p : precisions)
    out.push_back(net.forward(images, plucker, io.at("rays_o"), io.at("rays_d_un"), p).gaussians);
  return out;
}

TEST(ModelParity, BFloat16IsCloseToFloat32) {
  II_REQUIRE_SHARED(ckpt, "fixtures/official-tiny/weights.safetensors");
  const auto g = fixture_gaussians(ckpt, {Precision::Float32, Precision::BFloat16});
  const GaussianMaps &f32 = g[0], &bf16 = g[1];
  // bf16 has 8 mantissa bits: relative error ~ 2^-8 per product, a few units after 2 blocks.
  EXPECT_LT(max_abs(bf16.opacity, f32.opacity), 0.02);
  EXPECT_LT(max_abs(bf16.rgb, f32.rgb), 0.05);
  EXPECT_GT(max_abs(bf16.rgb, f32.rgb), 0.0);  // bf16 path really ran
  // Rotations are the head's 4 channels divided by their norm: where that norm is small (this
  // fixture's random weights), bf16's relative error becomes a large absolute one (0.07-0.10 on
  // the CPUs and the H100 measured).
  EXPECT_LT(max_abs(bf16.rotation, f32.rotation), 0.15);
}

TEST(ReleaseLayout, EveryReleaseKeyLoadsIntoTheReleasePreset) {
  II_REQUIRE_SHARED(path, "fixtures/official-tiny/release_state_dict_shapes.json");
  const auto shapes = nlohmann::json::parse(read_file_text(path));
  StateDict raw;
  for (const auto& [key, shape] : shapes.items()) raw[key] = torch::empty(shape.get<std::vector<int64_t>>());
  const StateDict state = normalize_state_dict(raw);
  const ModelConfig config = infer_config(state, nlohmann::json::object(), path.string());
  EXPECT_EQ(config.preset, "release");
  EXPECT_EQ(config.blocks, 24);
  EXPECT_EQ(config.embed_dim, 1024);
  Network net(ModelConfig::from_preset("release"), /*initialise=*/false);
  EXPECT_NO_THROW(net.load(state, path.string()));
}

}  // namespace parity_test
}  // namespace
}  // namespace ii
