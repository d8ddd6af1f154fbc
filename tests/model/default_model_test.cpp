// The default model shipped in models/default.safetensors and built into the library.
#include <gtest/gtest.h>

#include "model/checkpoint.h"
#include "model/default_model.h"
#include "model/network.h"
#include "test_support.h"

namespace ii {
namespace {

TEST(DefaultModel, IsEmbeddedAndRunsAsTheMiniInpaintingModel) {
  ASSERT_TRUE(has_default_model()) << "models/default.safetensors was not compiled in";
  const Checkpoint ck = checkpoint_or_default("");
  EXPECT_EQ(ck.config.preset, "mini");
  EXPECT_EQ(ck.config.image_channels, 4);  // stage 2: RGB + mask
  EXPECT_TRUE(ck.config.rgb_from_input);
  EXPECT_EQ(ck.config.scale_reference_height, 128) << "sizes of the 128-row pictures it was trained on";
  const Network net = network_from_checkpoint(ck, kDefaultModelName);

  torch::manual_seed(3);
  const int64_t V = 2, H = 16, W = 24;
  const torch::Tensor images = torch::rand({1, V, 4, H, W}) * 2 - 1;
  const torch::Tensor plucker = torch::randn({1, V, 6, H, W});
  const torch::Tensor rays_o = torch::zeros({1, V, H, W, 3});
  const torch::Tensor rays_d = torch::randn({1, V, H, W, 3});
  const GaussianMaps g = net.forward(images, plucker, rays_o, rays_d).gaussians;
  EXPECT_EQ(g.rgb.sizes(), (std::vector<int64_t>{1, V, 3, H, W}));
  for (const torch::Tensor& t : {g.depth, g.rgb, g.opacity, g.scale, g.rotation, g.xyz})
    EXPECT_TRUE(torch::isfinite(t).all().item<bool>());
  EXPECT_GT(g.depth.min().item<float>(), 0.f);
}

TEST(DefaultModel, AGivenCheckpointIsReadInstead) {
  const auto path = test::temp_dir("default-model") / "empty.safetensors";
  test::write_bytes(path, "");
  EXPECT_EQ(test::error_message([&] { checkpoint_or_default(path.string()); }),
            path.string() + ": not a PyTorch checkpoint: neither a zip archive (torch.save since 1.6) nor a legacy "
                            "torch.save stream");
}

}  // namespace
}  // namespace ii
