// Inception-v3 (FID features) with random weights: the layer table, the forward pass's
// shapes and batching, and the errors for wrong weight files.
#include <gtest/gtest.h>

#include <cstdlib>

#include "eval/inception.h"
#include "test_support.h"

namespace ii {
namespace {

namespace fs = std::filesystem;

WeightMap random_inception(uint64_t seed) {
  torch::manual_seed(seed);
  WeightMap w;
  for (const InceptionConvSpec& s : inception_conv_specs()) {
    w[s.name + ".conv.weight"] = torch::randn({s.out, s.in, s.kh, s.kw}) * std::sqrt(2.0 / (s.in * s.kh * s.kw));
    w[s.name + ".bn.weight"] = 1 + 0.1 * torch::rand({s.out});
    w[s.name + ".bn.bias"] = 0.05 * torch::randn({s.out});
    w[s.name + ".bn.running_mean"] = 0.05 * torch::randn({s.out});
    w[s.name + ".bn.running_var"] = 1 + 0.1 * torch::rand({s.out});
  }
  w["fc.weight"] = torch::zeros({1008, 2048});
  w["fc.bias"] = torch::zeros({1008});
  return w;
}

TEST(Inception, LayerTableHasTheFidNetworkShapes) {
  const auto& specs = inception_conv_specs();
  EXPECT_EQ(specs.size(), 94u);  // convolutions of Inception-v3 without the auxiliary head
  int64_t params = 0;
  for (const auto& s : specs) params += s.out * s.in * s.kh * s.kw;
  // With batch-norm pairs (2 x 17216 channels), fc (2048x1000 + 1000) and the auxiliary head
  // (2 557 696 + 769 000) this is torchvision's documented 27 161 264 parameters.
  EXPECT_EQ(params, 21751136);
  EXPECT_EQ(specs.front().name, "Conv2d_1a_3x3");
  EXPECT_EQ(specs.back().name, "Mixed_7c.branch_pool");
  EXPECT_EQ(specs.back().in, 2048);
}

TEST(Inception, FeaturesOfRandomWeights) {
  InceptionFeatures net(random_inception(1), "random");
  net.input_size = 75;  // the smallest size the network accepts: quick
  torch::manual_seed(2);
  const torch::Tensor images = torch::rand({3, 3, 40, 52});
  const torch::Tensor f = net.forward(images, 2);
  ASSERT_EQ(f.sizes(), (c10::IntArrayRef{3, 2048}));
  EXPECT_TRUE(torch::isfinite(f).all().item<bool>());
  EXPECT_GE(f.min().item<float>(), 0.f);  // means of ReLU outputs
  EXPECT_GT(f.max().item<float>(), 0.f);
  // Batching does not change the result.
  EXPECT_LT((net.forward(images, 1) - f).abs().max().item<float>(), 1e-4f);
  // Different images give different features.
  EXPECT_GT((f[0] - f[1]).abs().max().item<float>(), 1e-4f);
}

TEST(Inception, WrongWeightsNameTheProblem) {
  WeightMap w = random_inception(3);
  w.erase("Mixed_7c.branch_pool.bn.running_var");
  EXPECT_EQ(test::error_message([&] { InceptionFeatures(w, "fid.pth"); }),
            "fid.pth: no tensor Mixed_7c.branch_pool.bn.running_var (expected pytorch-fid's Inception-v3 state dict, "
            "pt_inception-2015-12-05-6726825d.pth)");
  WeightMap torchvision = random_inception(3);
  torchvision["fc.weight"] = torch::zeros({1000, 2048});
  EXPECT_EQ(test::error_message([&] { InceptionFeatures(torchvision, "inception_v3_google.pth"); }),
            "inception_v3_google.pth: fc.weight has 1000 outputs, not the 1008 of the FID Inception network (expected "
            "pytorch-fid's Inception-v3 state dict, pt_inception-2015-12-05-6726825d.pth)");
  WeightMap wrong = random_inception(3);
  wrong["Mixed_6b.branch7x7_2.conv.weight"] = torch::zeros({128, 128, 7, 1});
  EXPECT_EQ(test::error_message([&] { InceptionFeatures(wrong, "fid.pth"); }),
            "fid.pth: Mixed_6b.branch7x7_2.conv.weight has shape [128, 128, 7, 1], expected [128, 128, 1, 7] (expected "
            "pytorch-fid's Inception-v3 state dict, pt_inception-2015-12-05-6726825d.pth)");
}

TEST(Inception, MissingFileSaysWhatIsNeeded) {
  const char* saved = std::getenv(inception_env_var());
  const std::optional<std::string> keep = saved ? std::optional<std::string>(saved) : std::nullopt;
  unsetenv(inception_env_var());
  EXPECT_FALSE(inception_weights_path(std::nullopt));
  EXPECT_EQ(inception_missing_message(),
            "FID/KID need pytorch-fid's Inception-v3 weights (pt_inception-2015-12-05-6726825d.pth, from "
            "https://github.com/mseitzer/pytorch-fid/releases/download/fid_weights/"
            "pt_inception-2015-12-05-6726825d.pth), which are not redistributed with instainpaint: download it and "
            "pass --inception FILE or set INSTAINPAINT_FID_INCEPTION=FILE");
  EXPECT_EQ(test::error_message([] { inception_weights_path(fs::path("/nonexistent/fid.pth")); }),
            "/nonexistent/fid.pth: no such file (Inception weights for FID/KID)");
  EXPECT_EQ(test::error_message([] { InceptionFeatures::load("/nonexistent/fid.pth"); }),
            "/nonexistent/fid.pth: no such weight file");
  if (keep) setenv(inception_env_var(), keep->c_str(), 1);
}

}  // namespace
}  // namespace ii
