// LPIPS: heads from shared/data/lpips, the backbone layer layout against an independent
// torchvision-style module stack, identity/symmetry, gradients, masked and spatial variants,
// clear errors; the published reference value when a VGG16 backbone file is supplied.
#include <torch/nn.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>

#include "eval/lpips.h"
#include "io/image.h"
#include "io/safetensors.h"
#include "eval/metrics.h"
#include "tensor/image_tensor.h"
#include "random_lpips.h"
#include "test_support.h"

namespace ii {
namespace {

namespace fs = std::filesystem;
using test::random_backbone;
using test::random_heads;

// Clears an environment variable for one test and restores it afterwards.
class ScopedUnsetEnv {
 public:
  explicit ScopedUnsetEnv(const char* name) : name_(name) {
    if (const char* v = std::getenv(name)) saved_ = v;
    unsetenv(name);
  }
  ~ScopedUnsetEnv() {
    if (saved_) setenv(name_, saved_->c_str(), 1);
  }

 private:
  const char* name_;
  std::optional<std::string> saved_;
};

TEST(LpipsHeads, LoadWithTheRightShapes) {
  II_REQUIRE_SHARED(dir, "data/lpips");
  for (LpipsNet net : {LpipsNet::vgg, LpipsNet::alex}) {
    const auto heads = read_lpips_heads(dir / (std::string(lpips_net_name(net)) + ".safetensors"), net);
    const auto channels = lpips_stage_channels(net);
    ASSERT_EQ(heads.size(), 5u);
    for (size_t k = 0; k < heads.size(); ++k) {
      EXPECT_EQ(heads[k].sizes(), (c10::IntArrayRef{1, channels[k], 1, 1}));
      EXPECT_GE(heads[k].min().item<float>(), 0.f);  // trained with non-negativity clamping
      EXPECT_GT(heads[k].sum().item<float>(), 0.f);
    }
  }
  EXPECT_EQ(lpips_stage_channels(LpipsNet::vgg), (std::vector<int64_t>{64, 128, 256, 512, 512}));
  EXPECT_EQ(lpips_stage_channels(LpipsNet::alex), (std::vector<int64_t>{64, 192, 384, 256, 256}));
}

TEST(LpipsHeads, WrongNetworkIsAnError) {
  II_REQUIRE_SHARED(vgg, "data/lpips/vgg.safetensors");
  EXPECT_EQ(test::error_message([&] { read_lpips_heads(vgg, LpipsNet::alex); }),
            vgg.string() +
                ": lin1.model.1.weight has shape [1, 128, 1, 1], expected [1, 192, 1, 1] (expected the "
                "LPIPS v0.1 alex heads)");
}

// torchvision's `features` as a module stack (each module named by its index there), cut
// into the slices upstream LPIPS uses: VGG16 layers [0,4) [4,9) [9,16) [16,23) [23,30);
// AlexNet [0,2) [2,5) [5,8) [8,10) [10,12).
void reference_features(LpipsNet net, const WeightMap& w, torch::Tensor x, std::vector<torch::Tensor>& out) {
  using namespace torch::nn;
  std::vector<Sequential> slices;
  int index = 0;
  auto add = [&](auto module) { slices.back()->push_back(std::to_string(index++), module); };
  if (net == LpipsNet::vgg) {
    const std::vector<int> cfg = {64, 64, -1, 128, 128, -1, 256, 256, 256, -1, 512, 512, 512, -1, 512, 512, 512};
    const std::vector<int> slice_starts = {0, 4, 9, 16, 23};
    int64_t in = 3;
    for (int c : cfg) {
      if (std::find(slice_starts.begin(), slice_starts.end(), index) != slice_starts.end()) slices.emplace_back();
      if (c < 0) {
        add(MaxPool2d(MaxPool2dOptions(2).stride(2)));
        continue;
      }
      add(Conv2d(Conv2dOptions(in, c, 3).padding(1)));
      add(ReLU());
      in = c;
    }
  } else {
    slices.emplace_back();
    add(Conv2d(Conv2dOptions(3, 64, 11).stride(4).padding(2)));
    add(ReLU());
    slices.emplace_back();
    add(MaxPool2d(MaxPool2dOptions(3).stride(2)));
    add(Conv2d(Conv2dOptions(64, 192, 5).padding(2)));
    add(ReLU());
    slices.emplace_back();
    add(MaxPool2d(MaxPool2dOptions(3).stride(2)));
    add(Conv2d(Conv2dOptions(192, 384, 3).padding(1)));
    add(ReLU());
    slices.emplace_back();
    add(Conv2d(Conv2dOptions(384, 256, 3).padding(1)));
    add(ReLU());
    slices.emplace_back();
    add(Conv2d(Conv2dOptions(256, 256, 3).padding(1)));
    add(ReLU());
  }
  ASSERT_EQ(slices.size(), 5u);
  torch::NoGradGuard no_grad;
  for (Sequential& slice : slices)
    for (auto& item : slice->named_parameters()) {
      const std::string key = "features." + item.key();
      ASSERT_TRUE(w.count(key)) << key;
      item.value().copy_(w.at(key));
    }
  x = (x - torch::tensor({-0.030f, -0.088f, -0.188f}).view({1, 3, 1, 1})) /
      torch::tensor({0.458f, 0.448f, 0.450f}).view({1, 3, 1, 1});
  for (Sequential& slice : slices) {
    x = slice->forward(x);
    out.push_back(x / (x.pow(2).sum(1, true).sqrt() + 1e-10));
  }
}

TEST(Lpips, BackboneStagesMatchTorchvisionLayout) {
  for (LpipsNet net : {LpipsNet::vgg, LpipsNet::alex}) {
    const WeightMap w = random_backbone(net, 5);
    const Lpips lpips(net, w, random_heads(net), "random");
    const torch::Tensor x = torch::rand({1, 3, 64, 72}) * 2 - 1;
    const auto ours = lpips.features(x);
    std::vector<torch::Tensor> theirs;
    reference_features(net, w, x, theirs);
    ASSERT_EQ(ours.size(), theirs.size());
    for (size_t k = 0; k < ours.size(); ++k) {
      ASSERT_EQ(ours[k].sizes(), theirs[k].sizes()) << lpips_net_name(net) << " stage " << k;
      EXPECT_LT((ours[k] - theirs[k]).abs().max().item<float>(), 1e-5f) << lpips_net_name(net) << " stage " << k;
    }
  }
}

TEST(Lpips, DistanceIsTheHeadWeightedFeatureDifference) {
  const LpipsNet net = LpipsNet::alex;
  const Lpips lpips(net, random_backbone(net, 6), random_heads(net), "random");
  const torch::Tensor a = torch::rand({2, 3, 48, 40}) * 2 - 1, b = torch::rand({2, 3, 48, 40}) * 2 - 1;
  const auto fa = lpips.features(a), fb = lpips.features(b);
  torch::Tensor expected = torch::zeros({2});
  for (size_t k = 0; k < fa.size(); ++k)
    expected += ((fa[k] - fb[k]).pow(2) * lpips.heads()[k].view({1, -1, 1, 1})).sum(1).mean({1, 2});
  const torch::Tensor d = lpips.forward(a, b);
  ASSERT_EQ(d.sizes(), (c10::IntArrayRef{2}));
  EXPECT_LT((d - expected).abs().max().item<float>(), 1e-5f);
}

TEST(Lpips, IdentityZeroSymmetryAndGradients) {
  const LpipsNet net = LpipsNet::vgg;
  const Lpips lpips(net, random_backbone(net, 7), random_heads(net), "random");
  torch::manual_seed(8);
  const torch::Tensor a = torch::rand({1, 3, 32, 40}) * 2 - 1, b = torch::rand({1, 3, 32, 40}) * 2 - 1;
  EXPECT_EQ(lpips(a, a)[0].item<float>(), 0.f);
  const float ab = lpips(a, b)[0].item<float>(), ba = lpips(b, a)[0].item<float>();
  EXPECT_GT(ab, 0.f);
  EXPECT_NEAR(ab, ba, 1e-6f * std::max(1.f, ab));
  // Usable as a loss: gradients reach the inputs, finite even where the inputs coincide.
  torch::Tensor x = a.clone().requires_grad_(true);
  lpips(x, b).sum().backward();
  EXPECT_TRUE(torch::isfinite(x.grad()).all().item<bool>());
  EXPECT_GT(x.grad().abs().sum().item<float>(), 0.f);
  torch::Tensor same = a.clone().requires_grad_(true);
  lpips(same, a).sum().backward();
  EXPECT_TRUE(torch::isfinite(same.grad()).all().item<bool>());
}

TEST(Lpips, SpatialMapAndMaskedMean) {
  const LpipsNet net = LpipsNet::vgg;
  const Lpips lpips(net, random_backbone(net, 9), random_heads(net), "random");
  const torch::Tensor a = torch::rand({1, 3, 32, 48}) * 2 - 1, b = torch::rand({1, 3, 32, 48}) * 2 - 1;
  const torch::Tensor map = lpips.spatial_map(a, b);
  ASSERT_EQ(map.sizes(), (c10::IntArrayRef{1, 1, 32, 48}));
  EXPECT_GE(map.min().item<float>(), 0.f);
  EXPECT_EQ(lpips.spatial_map(a, a).abs().max().item<float>(), 0.f);
  // Sides divisible by 16: every stage's map is upsampled by an integer factor, which keeps
  // its mean, so the mean of the spatial map is the distance itself.
  EXPECT_NEAR(map.mean().item<float>(), lpips(a, b)[0].item<float>(), 1e-5);
  // An all-ones mask leaves the images as they are: the mean of the map.
  EXPECT_NEAR(lpips.masked(a, b, torch::ones({32, 48}))[0].item<float>(), map.mean().item<float>(), 1e-5);
  // Otherwise both images are multiplied by the mask in [0,1] first, then the map is
  // averaged over the mask.
  torch::Tensor mask = torch::zeros({1, 1, 32, 48});
  mask.narrow(2, 8, 16).narrow(3, 10, 20).fill_(1);
  const torch::Tensor am = ((a + 1) / 2 * mask) * 2 - 1, bm = ((b + 1) / 2 * mask) * 2 - 1;
  const torch::Tensor masked_map = lpips.spatial_map(am, bm);
  EXPECT_NEAR(lpips.masked(a, b, mask)[0].item<float>(),
              (masked_map * mask).sum().item<float>() / mask.sum().item<float>(), 1e-5);
}

TEST(Lpips, BadInputsNameTheProblem) {
  const Lpips lpips(LpipsNet::alex, random_backbone(LpipsNet::alex, 10), random_heads(LpipsNet::alex), "random");
  EXPECT_EQ(test::error_message([&] {
              lpips(torch::zeros({1, 3, 40, 40}), torch::zeros({1, 3, 40, 41}));
            }),
            "lpips: the images differ in shape: [1, 3, 40, 40] vs [1, 3, 40, 41]");
  EXPECT_EQ(test::error_message([&] {
              lpips(torch::zeros({1, 1, 40, 40}), torch::zeros({1, 1, 40, 40}));
            }),
            "lpips: first image must be (N, 3, H, W) or (3, H, W), got shape [1, 1, 40, 40]");
  EXPECT_EQ(test::error_message([&] {
              lpips(torch::zeros({1, 3, 20, 40}), torch::zeros({1, 3, 20, 40}));
            }),
            "lpips-alex: images of 40x20 pixels are too small (at least 31 pixels per side)");
  EXPECT_EQ(test::error_message([&] {
              lpips.masked(torch::zeros({1, 3, 40, 40}), torch::zeros({1, 3, 40, 40}), torch::ones({3, 3}));
            }),
            "masked lpips: mask of shape [3, 3] does not fit images of shape [1, 3, 40, 40]");
  WeightMap w = random_backbone(LpipsNet::alex, 11);
  w["features.3.weight"] = torch::zeros({192, 64, 3, 3});
  EXPECT_EQ(test::error_message([&] { Lpips(LpipsNet::alex, w, random_heads(LpipsNet::alex), "alex.pth"); }),
            "alex.pth: features.3.weight has shape [192, 64, 3, 3], expected [192, 64, 5, 5] (expected torchvision's "
            "AlexNet state dict, alexnet-owt-7be5be79.pth)");
}

TEST(Lpips, MissingBackboneFileSaysWhatIsNeeded) {
  ScopedUnsetEnv unset("INSTAINPAINT_LPIPS_VGG");
  EXPECT_FALSE(lpips_backbone_path(LpipsNet::vgg, std::nullopt));
  EXPECT_EQ(test::error_message([] { Lpips::load(LpipsNet::vgg); }),
            "LPIPS-vgg needs the ImageNet weights of torchvision's VGG16 (vgg16-397923af.pth, from "
            "https://download.pytorch.org/models/vgg16-397923af.pth), which are not redistributed with instainpaint: "
            "download it and pass --lpips-vgg FILE or set INSTAINPAINT_LPIPS_VGG=FILE");
  EXPECT_EQ(test::error_message([] { Lpips::load(LpipsNet::vgg, fs::path("/nonexistent/vgg16.pth")); }),
            "/nonexistent/vgg16.pth: no such file (LPIPS-vgg backbone weights)");
  setenv("INSTAINPAINT_LPIPS_VGG", "/nonexistent/env.pth", 1);
  EXPECT_EQ(test::error_message([] { lpips_backbone_path(LpipsNet::vgg, std::nullopt); }),
            "/nonexistent/env.pth: no such file (named by $INSTAINPAINT_LPIPS_VGG, the LPIPS-vgg backbone weights)");
  unsetenv("INSTAINPAINT_LPIPS_VGG");
}

TEST(Lpips, BackboneFileMissingAKey) {
  II_REQUIRE_SHARED(heads, "data/lpips/alex.safetensors");
  const fs::path file = test::temp_dir("lpips") / "partial.safetensors";
  const std::vector<float> zeros(64 * 3 * 11 * 11, 0.f);
  TensorData t{"F32",
               {64, 3, 11, 11},
               std::vector<uint8_t>(reinterpret_cast<const uint8_t*>(zeros.data()),
                                    reinterpret_cast<const uint8_t*>(zeros.data() + zeros.size()))};
  write_safetensors(file, {{"features.0.weight", t}});
  EXPECT_EQ(test::error_message([&] { Lpips::load(LpipsNet::alex, file, heads); }),
            file.string() +
                ": no tensor features.0.bias (expected torchvision's AlexNet state dict, "
                "alexnet-owt-7be5be79.pth)");
}

// The value quoted by brush from the PyTorch reference (see shared/data/lpips/PROVENANCE.md).
TEST(Lpips, ReferencePairWithSuppliedVggWeights) {
  II_REQUIRE_SHARED(dir, "data/lpips");
  const char* vgg = std::getenv("INSTAINPAINT_LPIPS_VGG");
  if (!vgg || !*vgg)
    GTEST_SKIP() << "set INSTAINPAINT_LPIPS_VGG to torchvision's vgg16-397923af.pth to check LPIPS-VGG(apple, pear) "
                    "= 0.6571019887924194";
  const Lpips lpips = Lpips::load(LpipsNet::vgg, std::nullopt, dir / "vgg.safetensors");
  const torch::Tensor apple = image_to_tensor(read_image_rgb(dir / "brush/apple.png")) * 2 - 1;
  const torch::Tensor pear = image_to_tensor(read_image_rgb(dir / "brush/pear.png")) * 2 - 1;
  EXPECT_NEAR(lpips(apple, pear)[0].item<double>(), 0.6571019887924194, 1e-4);
  EXPECT_LT(lpips(apple, apple)[0].item<double>(), 1e-5);
  EXPECT_NEAR(lpips(pear, apple)[0].item<double>(), lpips(apple, pear)[0].item<double>(), 1e-5);
}

}  // namespace
}  // namespace ii
