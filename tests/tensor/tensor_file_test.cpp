// Tensor files and images as LibTorch tensors.
#include <gtest/gtest.h>

#include "io/image.h"
#include "tensor/image_tensor.h"
#include "tensor/tensor_file.h"
#include "test_support.h"

namespace ii {
namespace {

namespace fs = std::filesystem;

TEST(TensorFile, EveryDtypeRoundTripsThroughSafetensors) {
  torch::manual_seed(1);
  const torch::Tensor base = torch::randn({2, 3}) * 40;
  std::vector<std::pair<std::string, torch::Tensor>> tensors;
  for (torch::ScalarType t : {torch::kFloat32, torch::kFloat16, torch::kBFloat16, torch::kFloat64, torch::kInt64,
                              torch::kInt32, torch::kInt16, torch::kInt8, torch::kUInt8, torch::kBool})
    tensors.emplace_back(c10::toString(t), base.to(t));
  tensors.emplace_back("empty", torch::zeros({0, 4}));
  tensors.emplace_back("strided view", base.t());  // written contiguous
  const fs::path path = test::temp_dir("tensor-file") / "all.safetensors";
  write_tensor_file(path, tensors, {{"note", "kept"}});
  EXPECT_TRUE(is_safetensors_file(path));
  const TensorMap back = read_tensor_file(path);
  ASSERT_EQ(back.size(), tensors.size());
  for (const auto& [name, t] : tensors) {
    ASSERT_TRUE(back.count(name)) << name;
    EXPECT_EQ(back.at(name).scalar_type(), t.scalar_type()) << name;
    EXPECT_TRUE(torch::equal(back.at(name), t)) << name;
  }
  EXPECT_EQ(read_safetensors(path).metadata.at("note"), "kept");
  EXPECT_EQ(test::error_message([] { data_from_tensor(torch::zeros({2}, torch::kComplexFloat)); }),
            "no safetensors dtype for a tensor of type ComplexFloat");
  EXPECT_EQ(test::error_message([&] { tensor_from_data(TensorData{"F8_E4M3", {1}, {0}}, path); }),
            path.string() + ": unsupported tensor dtype F8_E4M3");
}

// The mapped reading (weights copied on to a GPU) gives the tensors the copying one gives, and
// they outlive every handle of the file but their own.
TEST(TensorFile, MappedSafetensorsEqualTheCopiedOnes) {
  torch::manual_seed(2);
  std::vector<std::pair<std::string, torch::Tensor>> tensors = {
      {"a", torch::randn({5, 7})}, {"b", torch::randint(0, 100, {3}, torch::kInt64)}, {"empty", torch::zeros({0, 2})},
      {"half", torch::randn({4}).to(torch::kBFloat16)}};
  const fs::path path = test::temp_dir("tensor-file-mapped") / "m.safetensors";
  write_tensor_file(path, tensors, {{"config", "{}"}});
  std::map<std::string, std::string> metadata;
  torch::Tensor kept;
  {
    const TensorMap mapped = map_safetensors_tensors(path, &metadata);
    const TensorMap copied = read_tensor_file(path);
    ASSERT_EQ(mapped.size(), copied.size());
    for (const auto& [name, t] : copied) {
      EXPECT_EQ(mapped.at(name).scalar_type(), t.scalar_type()) << name;
      EXPECT_TRUE(torch::equal(mapped.at(name), t)) << name;
    }
    kept = mapped.at("a");
  }
  EXPECT_EQ(metadata.at("config"), "{}");
  fs::remove(path);  // the mapping stays while a tensor uses it
  EXPECT_TRUE(torch::equal(kept, tensors[0].second));
  EXPECT_EQ(test::error_message([&] { map_safetensors_tensors(path); }), path.string() + ": file not found");
}

TEST(TensorFile, PthAndSafetensorsOfTheFixtureHoldTheSameTensors) {
  II_REQUIRE_SHARED(dir, "fixtures/official-tiny");
  EXPECT_FALSE(is_safetensors_file(dir / "checkpoint.pth"));
  const TensorMap pth = read_tensor_file(dir / "checkpoint.pth");
  const TensorMap st = read_tensor_file(dir / "weights.safetensors");
  int compared = 0;
  for (const auto& [key, t] : pth) {
    // The .pth keeps DDP's "<module>.module.<name>" keys.
    std::string name = key;
    if (const size_t at = name.find(".module."); at != std::string::npos) name.erase(at, 7);
    if (!st.count(name)) continue;
    EXPECT_TRUE(torch::equal(t, st.at(name))) << key;
    ++compared;
  }
  EXPECT_EQ(compared, static_cast<int>(st.size()));
}

TEST(ImageTensor, ImagesRoundTripInBothLayouts) {
  Image image(3, 2, 3);
  for (size_t i = 0; i < image.pixels.size(); ++i) image.pixels[i] = static_cast<float>(i) / 17.f;
  const torch::Tensor nchw = image_to_tensor(image);
  ASSERT_EQ(nchw.sizes(), (std::vector<int64_t>{1, 3, 2, 3}));
  EXPECT_FLOAT_EQ(nchw[0][2][1][0].item<float>(), image.at(1, 0, 2));
  EXPECT_EQ(tensor_to_image(nchw).pixels, image.pixels);
  EXPECT_EQ(tensor_to_image(nchw[0].to(torch::kFloat64)).pixels, image.pixels);
  EXPECT_EQ(image_from_hwc(nchw[0].permute({1, 2, 0})).pixels, image.pixels);
  EXPECT_EQ(test::error_message([] { image_from_hwc(torch::zeros({2, 2})); }),
            "image_from_hwc: expected (H, W, C), got shape [2, 2]");
  EXPECT_EQ(test::error_message([] { tensor_to_image(torch::zeros({2, 3, 2, 2})); }),
            "tensor_to_image: expected one image, got a batch of 2");
}

}  // namespace
}  // namespace ii
