// Parity with the reference code (segment-anything's and MobileSAM's SamPredictor under PyPI's
// torch) on tests/segment/fixture/ (scripts/segmenter-reference/make-fixture.sh): small models
// of each published layout with seeded random weights, saved as their authors save theirs. The
// native image embedding, masks' logits at the photo's size, IoU scores and low-resolution
// logits equal the reference's within 1e-4 for one point, several points with a point that is
// not the object, a box, a box with a point, and a previous mask.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <tuple>

#include <nlohmann/json.hpp>

#include "common/parallel.h"
#include "io/image.h"
#include "segment/pillow_resize.h"
#include "segment/sam_model.h"
#include "segment/segmenter.h"
#include "tensor/tensor_file.h"
#include "test_support.h"

namespace ii {
namespace {
namespace segmenter_test {

const std::filesystem::path kFixture = "tests/segment/fixture";

float max_abs(const torch::Tensor& a, const torch::Tensor& b) {
  EXPECT_EQ(a.sizes(), b.sizes());
  if (a.sizes() != b.sizes()) return 1e9f;
  const float d = (a - b).abs().max().item<float>();
  return std::isnan(d) ? 1e9f : d;  // a NaN fails every bound
}

nlohmann::json cases() {
  std::ifstream in(kFixture / "cases.json");
  return nlohmann::json::parse(in);
}

SegmentPrompt prompt_of(const nlohmann::json& c, const std::map<std::string, Segmentation>& answers) {
  SegmentPrompt p;
  if (c.contains("points"))
    for (size_t i = 0; i < c["points"].size(); ++i)
      p.points.push_back({c["points"][i][0].get<double>(), c["points"][i][1].get<double>(), c["labels"][i].get<int>() == 1});
  if (c.contains("box")) p.box = std::array<double, 4>{c["box"][0], c["box"][1], c["box"][2], c["box"][3]};
  if (c.contains("mask_from")) {
    const Segmentation& from = answers.at(c["mask_from"].get<std::string>());
    p.previous = from.low_res[from.best()];
  }
  p.multimask = c["multimask"].get<bool>();
  return p;
}

// The largest difference of every answer from the reference's.
struct Differences {
  float features = 0, logits = 0, scores = 0, low_res = 0;
};

Differences compare_with_reference(const std::string& file, const std::string& prefix, int stride,
                                   SegmenterPrecision precision) {
  const TensorMap reference = read_tensor_file(kFixture / "reference.safetensors");
  const Segmenter segmenter = Segmenter::load(kFixture / file, precision);
  Differences d;
  const SegmenterImage image = segmenter.encode(read_image_rgb(kFixture / "image.png"));
  const torch::Tensor features = image.embedding[0].slice(1, 0, c10::nullopt, stride).slice(2, 0, c10::nullopt, stride);
  d.features = max_abs(features, reference.at(prefix + ".features"));
  std::map<std::string, Segmentation> answers;
  const nlohmann::json all = cases();
  EXPECT_EQ(all["cases"].size(), 5u);
  for (const nlohmann::json& c : all["cases"]) {
    const std::string name = c["name"];
    const Segmentation s = segmenter.segment(image, prompt_of(c, answers));
    const std::string key = prefix + "." + name;
    d.logits = std::max(d.logits, max_abs(s.logits, reference.at(key + ".logits")));
    d.scores = std::max(d.scores, max_abs(s.scores, reference.at(key + ".iou")));
    const torch::Tensor low = s.low_res.slice(1, 0, c10::nullopt, stride).slice(2, 0, c10::nullopt, stride);
    d.low_res = std::max(d.low_res, max_abs(low, reference.at(key + ".low_res")));
    answers.emplace(name, s);
  }
  return d;
}

void check_parity(const std::string& file, const std::string& prefix, int stride) {
  const Differences d = compare_with_reference(file, prefix, stride, SegmenterPrecision::Float32);
  EXPECT_LE(d.features, 1e-4f) << "image embedding";
  EXPECT_LE(d.logits, 1e-4f) << "masks' logits";
  EXPECT_LE(d.scores, 1e-4f) << "IoU scores";
  EXPECT_LE(d.low_res, 1e-4f) << "low-resolution logits";
}

TEST(SegmenterParity, SamVitLayoutEqualsTheReference) { check_parity("sam_vit_small.pth", "sam", 1); }

TEST(SegmenterParity, MobileSamTinyVitLayoutEqualsTheReference) { check_parity("mobile_sam_small.pt", "mobile_sam", 4); }

// bf16 products (the default where the CPU has native bf16) stay close to the reference: within
// 5 % of the logits' range on these fixtures (0.052 of 1.26 at most), 0.016 on the scores.
TEST(SegmenterParity, Bf16ProductsStayCloseToTheReference) {
  for (const auto& [file, prefix, stride] : {std::tuple{"sam_vit_small.pth", "sam", 1}, std::tuple{"mobile_sam_small.pt", "mobile_sam", 4}}) {
    const Differences d = compare_with_reference(file, prefix, stride, SegmenterPrecision::BFloat16);
    EXPECT_LE(d.logits, 0.08f) << prefix;
    EXPECT_LE(d.scores, 0.03f) << prefix;
  }
}

TEST(SegmenterParity, PhotosAreResizedAsPillowDoes) {
  const TensorMap reference = read_tensor_file(kFixture / "reference.safetensors");
  const Image rgb = read_image_rgb(kFixture / "image.png");
  Bytes8Image bytes{rgb.width, rgb.height, 3, {}};
  for (float v : rgb.pixels) bytes.pixels.push_back(static_cast<uint8_t>(std::lround(v * 255.f)));
  for (const int longest : {37, 131}) {
    const torch::Tensor expected = reference.at("resize." + std::to_string(longest));
    const Bytes8Image out = resize_like_pillow(bytes, static_cast<int>(expected.size(1)), static_cast<int>(expected.size(0)));
    const torch::Tensor got = torch::from_blob(const_cast<uint8_t*>(out.pixels.data()), expected.sizes(), torch::kUInt8);
    EXPECT_TRUE(torch::equal(got, expected)) << "longest side " << longest << ": "
                                             << (got.to(torch::kInt) - expected.to(torch::kInt)).abs().max().item<int>();
  }
}

}  // namespace segmenter_test
}  // namespace
}  // namespace ii

namespace ii {
namespace {
namespace segmenter_errors_test {

const std::filesystem::path kMobile = "tests/segment/fixture/mobile_sam_small.pt";

TEST(SegmenterFiles, AMissingTensorIsNamed) {
  TensorMap tensors = read_tensor_file(kMobile);
  tensors.erase("mask_decoder.transformer.layers.1.norm3.bias");
  EXPECT_EQ(test::error_message([&] { sam::model_from_tensors(tensors, "m.pt"); }),
            "m.pt: the tensor mask_decoder.transformer.layers.1.norm3.bias is missing (a SAM or MobileSAM checkpoint "
            "has it)");
}

TEST(SegmenterFiles, AWrongShapeIsNamed) {
  TensorMap tensors = read_tensor_file(kMobile);
  tensors["prompt_encoder.no_mask_embed.weight"] = torch::zeros({2, 32});
  EXPECT_EQ(test::error_message([&] { sam::model_from_tensors(tensors, "m.pt"); }),
            "m.pt: prompt_encoder.no_mask_embed.weight has shape [2, 32], expected [1, 32]");
}

TEST(SegmenterFiles, ASurplusTensorIsNamed) {
  TensorMap tensors = read_tensor_file(kMobile);
  tensors["image_encoder.extra.weight"] = torch::zeros({3});
  EXPECT_EQ(test::error_message([&] { sam::model_from_tensors(tensors, "m.pt"); }),
            "m.pt: 1 tensor(s) that no SAM or MobileSAM module has: image_encoder.extra.weight");
}

TEST(SegmenterFiles, AnotherNetworksCheckpointIsRefused) {
  const std::string missing = test::shared_missing("fixtures/official-tiny/checkpoint.pth");
  if (!missing.empty()) GTEST_SKIP() << missing;
  const std::filesystem::path other = test::shared_path("fixtures/official-tiny/checkpoint.pth");
  EXPECT_EQ(test::error_message([&] { Segmenter::load(other); }),
            other.string() + ": not a SAM or MobileSAM checkpoint (no mask_decoder.iou_token.weight; segment-anything's "
                             "sam_vit_b_01ec64.pth or MobileSAM's mobile_sam.pt are)");
}

TEST(SegmenterFiles, ATruncatedFileIsAnErrorNamingIt) {
  for (const std::filesystem::path& cut : test::truncated_copies(kMobile, test::temp_dir("segmenter-truncated"))) {
    const std::string message = test::error_message([&] { Segmenter::load(cut); });
    EXPECT_NE(message.find(cut.string()), std::string::npos) << message;
  }
}

TEST(SegmenterFiles, AnAbsentFileIsNamed) {
  EXPECT_EQ(test::error_message([&] { Segmenter::load("no/such/mobile_sam.pt"); }),
            "no/such/mobile_sam.pt: no such segmentation model file");
}

TEST(Segmenter, APromptNeedsSomething) {
  const Segmenter segmenter = Segmenter::load(kMobile, SegmenterPrecision::Float32);
  Image grey(40, 30, 3, 0.5f);
  const SegmenterImage image = segmenter.encode(grey);
  EXPECT_EQ(test::error_message([&] { segmenter.segment(image, {}); }),
            "a segmentation prompt needs a point, a box or a previous mask");
  EXPECT_EQ(test::error_message([&] { mask_from_prompt(segmenter, image, {}, {}, std::nullopt); }),
            "the segmenter needs a click on the object or a box around it");
  EXPECT_EQ(test::error_message([&] { parse_view_box("4,5,3,9", "--box"); }),
            "--box 4,5,3,9: expected X0,Y0,X1,Y1 with X1 > X0 and Y1 > Y0");
  EXPECT_EQ(parse_view_box("1.5,2,30,40.25", "--box"), (ViewBox{1.5, 2, 30, 40.25}));
}

// A click's mask brings only the best-scored of the three masks to the photo's size: the same
// pixels as all three brought there, and the others not at hand.
TEST(Segmenter, TheBestMaskAloneIsTheSameMask) {
  const Segmenter segmenter = Segmenter::load(kMobile, SegmenterPrecision::Float32);
  const Image photo = read_image_rgb("tests/segment/fixture/image.png");
  const SegmenterImage image = segmenter.encode(photo);
  SegmentPrompt prompt;
  prompt.points = {{photo.width * 0.4, photo.height * 0.6, true}};
  prompt.multimask = true;
  const Segmentation all = segmenter.segment(image, prompt), best = segmenter.segment(image, prompt, true);
  ASSERT_EQ(all.logits.size(0), 3);
  ASSERT_EQ(best.logits.size(0), 1);
  EXPECT_EQ(best.first, all.best());
  EXPECT_EQ(best.best(), all.best());
  // (the same arithmetic per pixel; LibTorch splits one channel and three differently over threads)
  EXPECT_LT((best.logits[0] - all.logits[all.best()]).abs().max().item<float>(), 1e-5f);
  EXPECT_EQ(best.mask(best.best()).pixels, all.mask(all.best()).pixels);
  const int other = (all.best() + 1) % 3;
  EXPECT_EQ(test::error_message([&] { best.mask(other); }),
            fmt::format("segmentation: mask {} was not brought to the photo's size", other));
}

// The encoder and decoder run OpenBLAS on one thread (beside LibTorch's team) and give it back.
TEST(Segmenter, OpenBlasRunsOneThreadWhileASegmenterWorks) {
  const Segmenter segmenter = Segmenter::load(kMobile, SegmenterPrecision::Float32);
  segmenter.encode(Image(40, 30, 3, 0.5f));  // OpenBLAS is set up by its first call
  const int before = openblas_threads();
  if (before == 0) GTEST_SKIP() << "LibTorch's BLAS here is not OpenBLAS";
  {
    const OneBlasThread outer;
    EXPECT_EQ(openblas_threads(), 1);
    { const OneBlasThread inner; }
    EXPECT_EQ(openblas_threads(), 1);  // until the last one ends
  }
  EXPECT_EQ(openblas_threads(), before);
}

}  // namespace segmenter_errors_test
}  // namespace
}  // namespace ii
