// LaMa natively (inpaint/lama.h) against the reference code: tests/inpaint/fixture/ is a small
// generator of big-lama's layout with seeded random weights, saved as big-lama's best.ckpt is
// (PyTorch Lightning's file), and the reference's inpainting of two photos, one of a size LaMa
// pads (scripts/inpainter-reference/make-fixture.sh).
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include <nlohmann/json.hpp>

#include "inpaint/lama.h"
#include "inpaint/lama_inpainter.h"
#include "io/file_hash.h"
#include "io/pth.h"
#include "tensor/tensor_file.h"
#include "test_support.h"

namespace ii {
namespace {

const std::filesystem::path kFixture = "tests/inpaint/fixture";
const std::filesystem::path kCheckpoint = kFixture / "lama-small" / "models" / "best.ckpt";

Image image_of(const torch::Tensor& t, float scale) {
  const torch::Tensor f = (t.to(torch::kFloat) * scale).contiguous();
  const int channels = t.dim() == 3 ? static_cast<int>(t.size(2)) : 1;
  Image out(static_cast<int>(t.size(1)), static_cast<int>(t.size(0)), channels);
  std::copy(f.data_ptr<float>(), f.data_ptr<float>() + f.numel(), out.pixels.begin());
  return out;
}

TEST(LamaParity, BigLamasLayoutEqualsTheReferenceAtTwoSizes) {
  const Lama lama = Lama::load(kCheckpoint);
  EXPECT_EQ(lama.description(), "LaMa FFC-ResNet (ngf 8, 2 blocks)");
  const TensorMap reference = read_tensor_file(kFixture / "reference.safetensors");
  std::ifstream in(kFixture / "cases.json");
  const nlohmann::json cases = nlohmann::json::parse(in)["cases"];
  ASSERT_EQ(cases.size(), 2u);
  for (size_t k = 0; k < cases.size(); ++k) {
    const std::string n = std::to_string(k);
    const Image photo = image_of(reference.at("image_" + n), 1.f / 255);
    const Image mask = image_of(reference.at("mask_" + n), 1.f / 255);
    ASSERT_EQ(photo.width, cases[k]["width"].get<int>());
    const Image painted = lama.inpaint(photo, mask);
    const Image expected = image_of(reference.at("inpainted_" + n), 1.f);
    ASSERT_EQ(painted.pixels.size(), expected.pixels.size());
    float worst = 0, changed = 0;
    for (size_t i = 0; i < painted.pixels.size(); ++i) {
      const float d = std::abs(painted.pixels[i] - expected.pixels[i]);
      worst = std::isnan(d) ? 1e9f : std::max(worst, d);
      changed = std::max(changed, std::abs(expected.pixels[i] - photo.pixels[i]));
    }
    // 6e-8 here (2026-12-06); the Fourier units' normalisation made 'backward' moves it by 1.5e-4.
    EXPECT_LE(worst, 1e-5f) << photo.width << "x" << photo.height;
    EXPECT_GT(changed, 0.05f) << "the region was painted";  // the comparison is not of the photo with itself
  }
}

// lama-cleaner's and IOPaint's big-lama.pt: the same generator traced to TorchScript. Its modules
// are objects whose attributes hold the weights: read as such, none of its code run.
TEST(LamaParity, TheTorchScriptFileGivesTheSameGenerator) {
  const Lama from_ckpt = Lama::load(kCheckpoint), from_script = Lama::load(kFixture / "big-lama.pt");
  EXPECT_EQ(from_script.description(), from_ckpt.description());
  const TensorMap reference = read_tensor_file(kFixture / "reference.safetensors");
  const Image photo = image_of(reference.at("image_1"), 1.f / 255), mask = image_of(reference.at("mask_1"), 1.f / 255);
  const Image a = from_ckpt.inpaint(photo, mask), b = from_script.inpaint(photo, mask);
  EXPECT_EQ(a.pixels, b.pixels);
}

// bf16 convolutions (the default on CPUs with native bf16) stay close to the reference's pixels.
TEST(LamaParity, Bf16StaysCloseToTheReference) {
  const Lama lama = Lama::load(kCheckpoint, /*bf16=*/true);
  EXPECT_TRUE(lama.bf16());
  const TensorMap reference = read_tensor_file(kFixture / "reference.safetensors");
  for (const std::string n : {"0", "1"}) {
    const Image painted = lama.inpaint(image_of(reference.at("image_" + n), 1.f / 255),
                                       image_of(reference.at("mask_" + n), 1.f / 255));
    const Image expected = image_of(reference.at("inpainted_" + n), 1.f);
    float worst = 0;
    for (size_t i = 0; i < painted.pixels.size(); ++i)
      worst = std::max(worst, std::isnan(painted.pixels[i]) ? 1e9f : std::abs(painted.pixels[i] - expected.pixels[i]));
    EXPECT_LE(worst, 0.002f) << n;  // 1.5e-4 here (2026-12-06)
  }
}

TEST(LamaFiles, ErrorsNameTheFileAndTheKey) {
  EXPECT_EQ(test::error_message([] { Lama::load("no/such/best.ckpt"); }), "no/such/best.ckpt: no such LaMa file");
  const std::filesystem::path sam = "tests/segment/fixture/mobile_sam_small.pt";
  EXPECT_EQ(test::error_message([&] { Lama::load(sam); }),
            sam.string() + ": no LaMa generator in it (model.1.ffc.convl2l.weight is missing; big-lama/models/best.ckpt "
                           "has it)");
  for (const std::filesystem::path& cut : test::truncated_copies(kCheckpoint, test::temp_dir("lama-files"))) {
    const std::string message = test::error_message([&] { Lama::load(cut); });
    EXPECT_NE(message.find(cut.string()), std::string::npos) << message;
  }
}

// Lightning keeps its callbacks' classes in the file: read as opaque values when asked for, and
// refused (naming the class) otherwise, as every other checkpoint is.
TEST(LamaFiles, LightningsClassesAreOpaqueNeverLoaded) {
  const std::string refused = test::error_message([] { read_pth_tensors(kCheckpoint); });
  EXPECT_NE(refused.find("'pytorch_lightning.callbacks.model_checkpoint.ModelCheckpoint'"), std::string::npos) << refused;
  PickleOptions options;
  options.opaque_objects = true;
  const auto tensors = read_pth_tensors(kCheckpoint, options);
  EXPECT_TRUE(tensors.count("state_dict.generator.model.1.ffc.convl2l.weight"));
  EXPECT_TRUE(tensors.count("state_dict.discriminator.model0.0.ffc.convl2l.weight"));
  const std::string extras = extras_to_json(read_pth(kCheckpoint, options));
  EXPECT_NE(extras.find("\"hparams\":{\"content\":{\"kind\":\"ffc_resnet\"}}"), std::string::npos) << extras;
}

// As the reference's inpainter: the region painted in a crop around it (brought down to at most
// 512 pixels when larger), the rest of the photo unchanged, bit for bit.
TEST(LamaInpainter, PaintsTheRegionInACropAndLeavesTheRest) {
  const Inpainter inpainter = inpainter_from_name(kCheckpoint.string());
  ASSERT_TRUE(inpainter.learned);
  EXPECT_EQ(inpainter.name(), "lama");
  EXPECT_EQ(inpainter.describe()["sha256"], sha256_of_file(kCheckpoint));
  for (const int width : {300, 1400}) {  // a crop at its size, and one brought down to 512
    Image photo(width, 900, 3), mask(width, 900, 1);
    for (int y = 0; y < photo.height; ++y)
      for (int x = 0; x < photo.width; ++x)
        for (int c = 0; c < 3; ++c) photo.at(y, x, c) = 0.5f + 0.4f * std::sin(0.05f * x + 0.07f * y + c);
    const int x0 = width / 4, x1 = width * 3 / 4;
    for (int y = 300; y < 700; ++y)
      for (int x = x0; x < x1; ++x) mask.at(y, x) = 1;
    const Image painted = inpainter.paint(photo, mask);
    int changed = 0, outside_changed = 0;
    for (int y = 0; y < photo.height; ++y)
      for (int x = 0; x < photo.width; ++x)
        for (int c = 0; c < 3; ++c) {
          const bool differs = painted.at(y, x, c) != photo.at(y, x, c);
          (mask.at(y, x) > 0.5f ? changed : outside_changed) += differs;
        }
    EXPECT_EQ(outside_changed, 0) << width;
    EXPECT_GT(changed, (x1 - x0) * 400) << width;  // most of the region's values repainted
  }
  EXPECT_EQ(test::error_message([] { inpainter_from_name("big-lama.ckpt"); }),
            "inpainter 'big-lama.ckpt': neither telea, ns, patch nor a LaMa file (big-lama/models/best.ckpt)");
  EXPECT_TRUE(inpainter_from_name("ns") == ClassicalInpainter::NavierStokes);
}

TEST(FileHash, Sha256AsSha256sumPrintsIt) {
  const std::filesystem::path file = test::temp_dir("sha256") / "abc.txt";
  test::write_bytes(file, "abc");
  EXPECT_EQ(sha256_of_file(file), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_NE(test::error_message([] { sha256_of_file("no/such/file"); }).find("no/such/file"), std::string::npos);
}

}  // namespace
}  // namespace ii
