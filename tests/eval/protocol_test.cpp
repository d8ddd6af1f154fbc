// The SPIn-NeRF protocol end to end on a synthetic scene with exact ground truth: a perfect
// prediction scores infinite PSNR and SSIM 1, an empty one the analytic value, a shifted one
// what its own renders give, and the two baselines what their definitions give.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>

#include <nlohmann/json.hpp>

#include "common/files.h"
#include "eval/lpips.h"
#include "eval/protocol.h"
#include "eval/truth_reference.h"
#include "io/image.h"
#include "model/default_model.h"
#include "model/scene_input.h"
#include "synth/synth_writer.h"
#include "synthetic_scene.h"
#include "tensor/image_tensor.h"
#include "test_support.h"

namespace ii {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

const fs::path& scene_dir() {
  static const fs::path dir = [] {
    const fs::path d = test::temp_dir("eval-scene") / "scene";
    test::write_scene(d);
    return d;
  }();
  return dir;
}

// Metric weights come only from what a test passes.
class Protocol : public ::testing::Test {
 protected:
  void SetUp() override {
    for (const char* v : {"INSTAINPAINT_LPIPS_VGG", "INSTAINPAINT_LPIPS_ALEX", "INSTAINPAINT_FID_INCEPTION"})
      unsetenv(v);
  }
  EvalOptions options(const std::string& tag) const {
    EvalOptions o;
    o.scene_dir = scene_dir();
    o.out = test::temp_dir("eval-" + tag);
    o.height = test::kSceneHeight;
    o.device = torch::kCPU;
    o.gaussians_normalized = true;  // the test scene's splat files are made in the pose-normalised frame
    return o;
  }
};

bool in_mask(int y, int x) {
  return y >= test::kMaskY0 && y < test::kMaskY1 && x >= test::kMaskX0 && x < test::kMaskX1;
}

struct Errors {
  double mse = 0, masked_mse = 0;
};
// Mean squared errors of `predicted` against a view's ground-truth file, in double.
Errors errors_against_truth(const View& view, const Image& predicted) {
  const Image truth = load_view_image(view);
  double sum = 0, masked = 0;
  int masked_count = 0;
  for (int y = 0; y < truth.height; ++y)
    for (int x = 0; x < truth.width; ++x)
      for (int c = 0; c < 3; ++c) {
        const double d = double(truth.at(y, x, c)) - predicted.at(y, x, c);
        sum += d * d;
        if (in_mask(y, x)) {
          masked += d * d;
          ++masked_count;
        }
      }
  return {sum / (truth.width * truth.height * 3), masked / masked_count};
}

double psnr_of(double mse) { return -10 * std::log10(mse); }

// The stage of metrics.json's "stages" by name (null when absent), and the names in order of
// the stages run on the main thread, or of those run behind it (in the order they happened to
// start: compare them as a set).
json stage(const json& m, const std::string& name) {
  for (const json& s : m["stages"])
    if (s["stage"] == name) return s;
  return nullptr;
}
std::vector<std::string> stage_names(const json& m, bool behind = false) {
  std::vector<std::string> names;
  for (const json& s : m["stages"])
    if (s.value("behind", false) == behind) names.push_back(s["stage"]);
  return names;
}

TEST_F(Protocol, PerfectPredictionScoresInfinity) {
  EvalOptions o = options("perfect");
  o.gaussians = scene_dir() / "truth.ply";
  const json m = run_evaluation(o);

  ASSERT_EQ(m["views"].size(), 2u);
  EXPECT_EQ(m["views"][0]["name"], "00_test");
  EXPECT_EQ(m["views"][1]["name"], "01_test");
  EXPECT_EQ(m["working_size"], json::array({test::kSceneWidth, test::kSceneHeight}));
  for (const json& v : m["views"]) {
    EXPECT_EQ(v["psnr"], "inf");
    EXPECT_EQ(v["masked_psnr"], "inf");
    EXPECT_EQ(v["box_psnr"], "inf");
    EXPECT_NEAR(v["ssim"].get<double>(), 1.0, 1e-6);
    EXPECT_NEAR(v["masked_ssim"].get<double>(), 1.0, 1e-6);
    EXPECT_EQ(v["mask_pixels"], (test::kMaskX1 - test::kMaskX0) * (test::kMaskY1 - test::kMaskY0));
  }
  EXPECT_EQ(m["mean"]["psnr"], "inf");
  EXPECT_NEAR(m["mean"]["ssim"].get<double>(), 1.0, 1e-6);
  EXPECT_EQ(m["prediction"]["source"], "gaussians");
  EXPECT_EQ(m["prediction"]["gaussians"], 71 * 51);

  // Without weights, LPIPS and FID/KID are reported unavailable with the reason.
  EXPECT_TRUE(m["mean"]["lpips"].is_null());
  EXPECT_EQ(m["unavailable"]["lpips"], lpips_missing_backbone_message(LpipsNet::vgg));
  EXPECT_EQ(m["unavailable"]["masked_lpips"], lpips_missing_backbone_message(LpipsNet::vgg));
  for (const char* k : {"fid", "kid", "c_fid", "c_kid"}) {
    EXPECT_TRUE(m["set"][k].is_null()) << k;
    EXPECT_TRUE(m["unavailable"][k].get<std::string>().rfind("FID/KID need pytorch-fid's Inception-v3", 0) == 0) << k;
  }
  // Where the time went: each stage once, in the order they first ran, a render per test view,
  // the files' encoding behind the main work.
  EXPECT_EQ(stage_names(m),
            std::vector<std::string>({"read scene", "read gaussians", "gaussians to the renderer", "load metric networks",
                                      "decode test views (waited)", "upload test views", "render", "download renders",
                                      "image metrics", "write files (waited)", "write report"}));
  std::vector<std::string> behind = stage_names(m, true);
  std::sort(behind.begin(), behind.end());
  EXPECT_EQ(behind, std::vector<std::string>({"write contact sheets", "write renders"}));
  EXPECT_EQ(stage(m, "render")["calls"], 2);
  EXPECT_EQ(stage(m, "write renders")["behind"], true);
  EXPECT_FALSE(stage(m, "render").contains("behind"));
  double waited = 0;
  for (const json& s : m["stages"]) {
    EXPECT_GE(s["ms"].get<double>(), 0.0) << s;
    if (!s.contains("behind")) waited += s["ms"].get<double>();
  }
  const json& t = m["timings"];
  EXPECT_DOUBLE_EQ(t["waited_ms"].get<double>(), waited);
  EXPECT_LE(t["waited_ms"].get<double>(), t["total_ms"].get<double>());
  EXPECT_DOUBLE_EQ(t["compute_ms"].get<double>(),
                   stage(m, "gaussians to the renderer")["ms"].get<double>() +
                       stage(m, "upload test views")["ms"].get<double>() + stage(m, "render")["ms"].get<double>() +
                       stage(m, "download renders")["ms"].get<double>() + stage(m, "image metrics")["ms"].get<double>());

  // Files: metrics.json is what was returned; the renders equal the ground truth; the
  // report shows every view's sheet (4 panels with 4-pixel gaps).
  EXPECT_EQ(json::parse(read_file_text(o.out / "metrics.json")), m);
  const Scene scene = load_scene(scene_dir());
  for (const View& v : scene.test_views) {
    EXPECT_EQ(read_image_rgb(o.out / "renders" / (v.name + ".png")).pixels, load_view_image(v).pixels);
    const ImageInfo sheet = probe_image(o.out / "sheets" / (v.name + ".png"));
    EXPECT_EQ(sheet.width, 4 * test::kSceneWidth + 3 * 4);
    EXPECT_EQ(sheet.height, test::kSceneHeight);
  }
  const std::string html = read_file_text(o.out / "report.html");
  EXPECT_NE(html.find("sheets/00_test.png"), std::string::npos);
  EXPECT_NE(html.find("sheets/01_test.png"), std::string::npos);
}

TEST_F(Protocol, SplatsInTheScenesFrameRenderAsTheTruth) {
  // truth.ply moved to the scene's frame (where infer and 3DGS trainers write): evaluated as the
  // scene's by default, it scores as the truth does; taken for the normalised frame, it does not.
  const Scene scene = load_scene(scene_dir());
  const fs::path ply = test::temp_dir("eval-scene-frame") / "truth-scene.ply";
  write_splat_ply(ply, splats_from_gaussians(
                           in_scene_frame(gaussians_from_splats(read_splat_ply(scene_dir() / "truth.ply")), scene_normalization(scene))));
  EvalOptions o = options("scene-frame");
  o.gaussians = ply;
  o.gaussians_normalized = false;
  const json m = run_evaluation(o);
  EXPECT_EQ(m["prediction"]["frame"], "scene");
  for (const json& v : m["views"]) EXPECT_TRUE(v["psnr"] == "inf" || v["psnr"].get<double>() > 45) << v["psnr"];
  o.gaussians_normalized = true;
  o.out = test::temp_dir("eval-scene-frame-as-normalized");
  const json wrong = run_evaluation(o);
  for (const json& v : wrong["views"]) EXPECT_LT(v["psnr"].get<double>(), 25);
}

TEST_F(Protocol, EmptyPredictionScoresTheWhiteBackground) {
  // Every splat moved behind the cameras: the renders are the white background.
  const fs::path ply = test::temp_dir("eval-empty-ply") / "behind.ply";
  write_splat_ply(ply, test::wall_of_splats(0.f, 10.f));
  EvalOptions o = options("empty");
  o.gaussians = ply;
  const json m = run_evaluation(o);
  const Scene scene = load_scene(scene_dir());
  for (size_t i = 0; i < scene.test_views.size(); ++i) {
    const Errors e = errors_against_truth(scene.test_views[i], Image(test::kSceneWidth, test::kSceneHeight, 3, 1.f));
    EXPECT_NEAR(m["views"][i]["psnr"].get<double>(), psnr_of(e.mse), 1e-3);
    EXPECT_NEAR(m["views"][i]["masked_psnr"].get<double>(), psnr_of(e.masked_mse), 1e-3);
  }
}

TEST_F(Protocol, ShiftedPredictionScoresItsOwnRenders) {
  const fs::path ply = test::temp_dir("eval-shift-ply") / "shifted.ply";
  const SplatCloud shifted = test::wall_of_splats(0.15f);
  write_splat_ply(ply, shifted);
  EvalOptions o = options("shifted");
  o.gaussians = ply;
  const json m = run_evaluation(o);
  const Scene scene = load_scene(scene_dir());
  double mean = 0;
  for (size_t i = 0; i < scene.test_views.size(); ++i) {
    const View& v = scene.test_views[i];
    const Image predicted = quantize_image(test::render_view(scene, v, shifted), "round");
    const Errors e = errors_against_truth(v, predicted);
    ASSERT_GT(e.mse, 0);
    EXPECT_NEAR(m["views"][i]["psnr"].get<double>(), psnr_of(e.mse), 1e-3) << v.name;
    EXPECT_NEAR(m["views"][i]["masked_psnr"].get<double>(), psnr_of(e.masked_mse), 1e-3) << v.name;
    EXPECT_LT(m["views"][i]["ssim"].get<double>(), 0.999);
    mean += psnr_of(e.mse) / 2;
  }
  EXPECT_NEAR(m["mean"]["psnr"].get<double>(), mean, 1e-3);
}

TEST_F(Protocol, MeanFillBaseline) {
  EvalOptions o = options("mean-fill");
  o.method = EvalMethod::mean_fill;
  o.ring_width = 3;
  const json m = run_evaluation(o);
  EXPECT_EQ(m["method"], "mean-fill");
  const Scene scene = load_scene(scene_dir());
  for (size_t i = 0; i < scene.test_views.size(); ++i) {
    const Image truth = load_view_image(scene.test_views[i]);
    // The ring: pixels within 3 (Chebyshev) of the mask rectangle, outside it.
    double sum[3] = {0, 0, 0};
    int count = 0;
    for (int y = test::kMaskY0 - 3; y < test::kMaskY1 + 3; ++y)
      for (int x = test::kMaskX0 - 3; x < test::kMaskX1 + 3; ++x)
        if (!in_mask(y, x)) {
          for (int c = 0; c < 3; ++c) sum[c] += truth.at(y, x, c);
          ++count;
        }
    Image expected = truth;
    for (int y = test::kMaskY0; y < test::kMaskY1; ++y)
      for (int x = test::kMaskX0; x < test::kMaskX1; ++x)
        for (int c = 0; c < 3; ++c) expected.at(y, x, c) = std::lround(sum[c] / count * 255) / 255.f;
    const Errors e = errors_against_truth(scene.test_views[i], expected);
    EXPECT_NEAR(m["views"][i]["psnr"].get<double>(), psnr_of(e.mse), 1e-3);
    EXPECT_NEAR(m["views"][i]["masked_psnr"].get<double>(), psnr_of(e.masked_mse), 1e-3);
    EXPECT_EQ(read_image_rgb(o.out / "renders" / (scene.test_views[i].name + ".png")).pixels, expected.pixels);
  }
}

TEST_F(Protocol, TeleaBaselineChangesOnlyTheMask) {
  EvalOptions o = options("telea");
  o.method = EvalMethod::telea;
  const json m = run_evaluation(o);
  const Scene scene = load_scene(scene_dir());
  for (size_t i = 0; i < scene.test_views.size(); ++i) {
    const Image truth = load_view_image(scene.test_views[i]);
    const Image filled = read_image_rgb(o.out / "renders" / (scene.test_views[i].name + ".png"));
    double outside = 0;
    for (int y = 0; y < truth.height; ++y)
      for (int x = 0; x < truth.width; ++x)
        if (!in_mask(y, x))
          for (int c = 0; c < 3; ++c) outside += std::abs(truth.at(y, x, c) - filled.at(y, x, c));
    EXPECT_EQ(outside, 0.0);
    const double psnr = m["views"][i]["psnr"].get<double>(), masked = m["views"][i]["masked_psnr"].get<double>();
    EXPECT_TRUE(std::isfinite(psnr));
    // All the error lies in the mask, 256 of the 3072 pixels.
    EXPECT_NEAR(psnr, masked + 10 * std::log10(3072.0 / 256.0), 1e-3);
  }
}

TEST_F(Protocol, NetworkPredictionFromACheckpoint) {
  // The tiny official-layout model (random weights): checks the whole model path, not quality.
  II_REQUIRE_SHARED(checkpoint, "fixtures/official-tiny/checkpoint.pth");
  EvalOptions o = options("network");
  o.checkpoint = checkpoint;
  o.context = {"03", "02", "04", "05"};
  const json m = run_evaluation(o);
  EXPECT_EQ(m["prediction"]["source"], "network");
  EXPECT_EQ(m["prediction"]["checkpoint"], checkpoint.string());
  EXPECT_EQ(m["prediction"]["context"], json::array({"03", "02", "04", "05"}));
  EXPECT_EQ(m["prediction"]["reference"], "ns");
  // One Gaussian a pixel, then those past the frames (an eighth of the height past each edge, then
  // sparser to a quarter) but those another view sees through, then those behind depth edges,
  // then the reference's region covered, a splat a pixel of it.
  const int margin = static_cast<int>(std::lround(test::kSceneHeight / 8.0));
  const int past = (test::kSceneWidth + 2 * margin) * (test::kSceneHeight + 2 * margin) - test::kSceneWidth * test::kSceneHeight;
  // Out to a quarter of the height, one per 2 x 2 block past that (the sizes here are even).
  const int outer = static_cast<int>(std::lround(test::kSceneHeight / 4.0));
  const int blocks = ((test::kSceneWidth + 2 * outer) / 2) * ((test::kSceneHeight + 2 * outer) / 2) -
                     ((test::kSceneWidth + 2 * margin) / 2) * ((test::kSceneHeight + 2 * margin) / 2);
  const int64_t region = m["prediction"]["geometry"]["region_cover"]["gaussians"];
  EXPECT_GT(region, 0);
  const int64_t dropped = m["prediction"]["geometry"]["frame_margin"]["dropped"];
  const int64_t behind = m["prediction"]["geometry"]["behind_edges"]["gaussians"];
  EXPECT_EQ(m["prediction"]["gaussians"],
            4 * (test::kSceneWidth * test::kSceneHeight + past + blocks) - dropped + behind + region);
  EXPECT_EQ(m["prediction"]["geometry"]["frame_margin"]["pixels"], margin);
  // The prediction's stages come first; computation is the work between the files.
  const std::vector<std::string> names = stage_names(m);
  ASSERT_GE(names.size(), 18u);
  EXPECT_EQ(std::vector<std::string>(names.begin(), names.begin() + 18),
            std::vector<std::string>({"read scene", "load model: read checkpoint", "load model: network from checkpoint",
                                      "load model: weights to cpu", "prepare context views",
                                      "inpaint reference (ns)", "network input", "upload", "network",
                                      "the scene's points", "align depth to the scene's points",
                                      "the measured depth (the photos (stereo))", "the measured surface",
                                      "the region on the surface around it",
                                      "fade floaters", "Gaussians past the frames", "the region's cover",
                                      "gaussians to the renderer"}));
  EXPECT_EQ(m["prediction"]["geometry"]["source"], "none");  // the test scene has no depth maps or points
  EXPECT_EQ(m["prediction"]["geometry"]["detail"], DepthDetailOptions().detail);
  ASSERT_EQ(m["prediction"]["own_views"]["views"].size(), 4u);
  EXPECT_TRUE(m["prediction"]["own_views"]["mean_psnr_outside_mask"].is_number());
  const json& t = m["timings"];
  double compute = 0;
  for (const char* k : {"upload", "network", "gaussians to the renderer", "upload test views", "render",
                        "download renders", "image metrics"})
    compute += stage(m, k)["ms"].get<double>();
  EXPECT_DOUBLE_EQ(t["compute_ms"].get<double>(), compute);
  EXPECT_LT(t["compute_ms"].get<double>(), t["total_ms"].get<double>());
  for (const json& v : m["views"]) {
    EXPECT_TRUE(v["psnr"].is_number());
    EXPECT_TRUE(v["masked_ssim"].is_number());
  }
}

TEST_F(Protocol, WithoutACheckpointTheDefaultModelRuns) {
  EvalOptions o = options("default-model");
  o.context = {"03", "02", "04", "05"};
  if (!has_default_model()) {
    EXPECT_EQ(test::error_message([&] { run_evaluation(o); }),
              "this build has no default model (models/default.safetensors was absent when it was configured): "
              "give --checkpoint");
    return;
  }
  const json m = run_evaluation(o);
  EXPECT_EQ(m["prediction"]["checkpoint"], kDefaultModelName);
  EXPECT_EQ(m["prediction"]["config"]["preset"], "mini");
  EXPECT_TRUE(std::isfinite(m["mean"]["masked_psnr"].get<double>()));
}

// The ground-truth-reference protocol: an object-free test view first in the context is the
// reference, its own photo the reference image, and only the other test views are scored; the
// region and the whole image side by side.
TEST_F(Protocol, AnObjectFreeTestViewAsTheReferenceIsItsOwnPhotoAndIsNotScored) {
  if (!has_default_model()) GTEST_SKIP() << "this build has no default model";
  EvalOptions o = options("truth-reference");
  o.context = {"00_test", "02", "03", "04"};
  const json m = run_evaluation(o);
  EXPECT_EQ(m["prediction"]["reference_protocol"]["view"], "00_test");
  EXPECT_EQ(m["prediction"]["reference"], (scene_dir() / "images" / "00_test.png").string());
  EXPECT_EQ(m["prediction"]["context"], json::array({"00_test", "02", "03", "04"}));
  ASSERT_EQ(m["views"].size(), 1u);
  EXPECT_EQ(m["views"][0]["name"], "01_test");
  const json& rw = m["region_and_whole"];
  EXPECT_EQ(rw["psnr"]["whole"], m["mean"]["psnr"]);
  EXPECT_EQ(rw["psnr"]["region"], m["mean"]["masked_psnr"]);
  EXPECT_DOUBLE_EQ(rw["psnr"]["region_minus_whole"].get<double>(),
                   m["mean"]["masked_psnr"].get<double>() - m["mean"]["psnr"].get<double>());
  EXPECT_EQ(rw["ssim"]["region"], m["mean"]["masked_ssim"]);
}

// A splat file scored with a test view as the reference (as a fill made from it): that view is
// left out; the region's uncovered pixels are counted, all of them where nothing renders.
TEST_F(Protocol, SplatsScoredWithoutTheReferenceViewAndTheirUncoveredPixelsCounted) {
  EvalOptions o = options("truth-reference-splats");
  o.gaussians = scene_dir() / "truth.ply";
  o.reference_view = "01_test";
  const json truth = run_evaluation(o);
  ASSERT_EQ(truth["views"].size(), 1u);
  EXPECT_EQ(truth["views"][0]["name"], "00_test");
  EXPECT_EQ(truth["views"][0]["uncovered_pixels"], 0);
  EXPECT_EQ(truth["region_and_whole"]["uncovered"]["pixels"], 0);
  EXPECT_EQ(truth["region_and_whole"]["uncovered"]["views"], 0);

  const fs::path behind = test::temp_dir("eval-uncovered") / "behind.ply";
  write_splat_ply(behind, test::wall_of_splats(0.f, 10.f));
  EvalOptions empty = options("uncovered");
  empty.gaussians = behind;
  const json m = run_evaluation(empty);
  ASSERT_EQ(m["views"].size(), 2u);
  int64_t mask_pixels = 0;
  for (const json& v : m["views"]) {
    EXPECT_EQ(v["uncovered_pixels"], v["mask_pixels"]);
    EXPECT_GT(v["mask_pixels"].get<int64_t>(), 0);
    mask_pixels += v["mask_pixels"].get<int64_t>();
  }
  EXPECT_EQ(m["region_and_whole"]["uncovered"]["pixels"], mask_pixels);
  EXPECT_EQ(m["region_and_whole"]["uncovered"]["views"], 2);
  EvalOptions wrong = options("truth-reference-wrong");
  wrong.gaussians = scene_dir() / "truth.ply";
  wrong.reference_view = "02";
  EXPECT_EQ(test::error_message([&] { run_evaluation(wrong); }),
            scene_dir().string() + ": 02 is not an object-free test view: with --gaussians the reference view names "
                                   "the test view the splats were filled from, which is then not scored");
}

TEST(TruthReference, MovesAnObjectFreeTestViewToTheInputsOnly) {
  Scene scene;
  scene.root = "scene";
  View input, object_free, no_mask, held_out;
  input.name = "a";
  object_free.name = "t";
  object_free.mask_path = "t.png";
  object_free.image_path = "images/t.png";
  no_mask.name = "u";
  held_out.name = "h";
  held_out.mask_path = "h.png";
  held_out.shows_object = true;
  scene.views = {input};
  scene.test_views = {object_free, no_mask, held_out};
  EXPECT_FALSE(take_truth_reference(scene, "a").has_value());
  EXPECT_FALSE(take_truth_reference(scene, "h").has_value()) << "a held-out view shows the object";
  EXPECT_FALSE(take_truth_reference(scene, "").has_value());
  EXPECT_EQ(test::error_message([&] { take_truth_reference(scene, "u"); }),
            "scene: test view u has no mask in test_label/: as the reference its mask is the region");
  const auto truth = take_truth_reference(scene, "t");
  ASSERT_TRUE(truth.has_value());
  EXPECT_EQ(truth->photo, "images/t.png");
  ASSERT_EQ(scene.views.size(), 2u);
  EXPECT_EQ(scene.views[1].name, "t");
  ASSERT_EQ(scene.test_views.size(), 2u);
  EXPECT_EQ(scene.test_views[0].name, "u");
}

// The agreement target on a GPU: the default model's bf16 fast path on the GPU (network,
// CUDA rasterizer, metrics on the device) against the float32 CPU path: renders at least 40 dB
// apart, the same metrics.
TEST_F(Protocol, GpuEvaluationAgreesWithTheCpu) {
  II_REQUIRE_CUDA();
  if (!has_default_model()) GTEST_SKIP() << "built without the default model";
  EvalOptions cpu = options("cpu-f32");
  cpu.context = {"03", "02", "04", "05"};
  cpu.quantize = "none";
  EvalOptions gpu = cpu;
  gpu.out = test::temp_dir("eval-gpu-bf16");
  gpu.device = torch::kCUDA;
  gpu.precision = Precision::BFloat16;
  const json a = run_evaluation(cpu), b = run_evaluation(gpu);
  EXPECT_EQ(b["device"], "cuda:0");
  ASSERT_EQ(a["views"].size(), b["views"].size());
  for (size_t i = 0; i < a["views"].size(); ++i) {
    const std::string file = a["views"][i]["files"]["render"];
    const torch::Tensor x = image_to_tensor(read_image_rgb(cpu.out / file)),
                        y = image_to_tensor(read_image_rgb(gpu.out / file));
    EXPECT_GE(psnr(x, y)[0].item<double>(), 40.0) << file;
    EXPECT_NEAR(a["views"][i]["psnr"].get<double>(), b["views"][i]["psnr"].get<double>(), 0.2) << file;
    EXPECT_NEAR(a["views"][i]["masked_ssim"].get<double>(), b["views"][i]["masked_ssim"].get<double>(), 0.01) << file;
  }
}

TEST_F(Protocol, BadRequestsNameTheProblem) {
  EvalOptions o = options("errors");
  o.gaussians = scene_dir() / "truth.ply";
  o.checkpoint = scene_dir() / "truth.ply";
  EXPECT_EQ(test::error_message([&] { run_evaluation(o); }), "eval: give either --checkpoint or --gaussians, not both");
  o.checkpoint.reset();
  o.method = EvalMethod::telea;
  EXPECT_EQ(test::error_message([&] { run_evaluation(o); }),
            "eval --method telea is a baseline without a model: drop --checkpoint/--gaussians");
  o.method = EvalMethod::model;
  o.quantize = "floor";
  EXPECT_EQ(test::error_message([&] { run_evaluation(o); }),
            "--quantize: unknown mode 'floor' (expected round, truncate or none)");
  o.quantize = "round";
  o.lpips_vgg = "/nonexistent/vgg16.pth";
  EXPECT_EQ(test::error_message([&] { run_evaluation(o); }),
            "/nonexistent/vgg16.pth: no such file (LPIPS-vgg backbone weights)");

  const fs::path no_tests = test::temp_dir("eval-no-tests") / "scene";
  test::write_scene(no_tests, /*with_test_views=*/false);
  EvalOptions p = options("no-tests");
  p.scene_dir = no_tests;
  p.gaussians = no_tests / "truth.ply";
  EXPECT_EQ(test::error_message([&] { run_evaluation(p); }),
            no_tests.string() +
                ": no test views (SPIn-NeRF scenes list object-free ones by their masks in images_K/test_label/; "
                "--hold-out-every N holds out input views that have masks)");
}

TEST_F(Protocol, HeldOutViewsCompareOutsideTheirMasks) {
  // A scene without object-free test views: every third input view is held out. Those show
  // the object, so only the pixels outside their masks are compared.
  const fs::path dir = test::temp_dir("eval-hold-out") / "scene";
  test::write_scene(dir, /*with_test_views=*/false);
  const fs::path ply = test::temp_dir("eval-hold-out-ply") / "shifted.ply";
  const SplatCloud shifted = test::wall_of_splats(0.15f);
  write_splat_ply(ply, shifted);
  EvalOptions o = options("hold-out");
  o.scene_dir = dir;
  o.scene.hold_out_every = 3;
  o.gaussians = ply;
  const json m = run_evaluation(o);

  const Scene scene = load_scene(dir, o.scene);
  ASSERT_EQ(scene.test_views.size(), 2u);
  ASSERT_EQ(m["views"].size(), 2u);
  for (size_t i = 0; i < scene.test_views.size(); ++i) {
    const View& v = scene.test_views[i];
    EXPECT_TRUE(v.shows_object);
    const Image predicted = quantize_image(test::render_view(scene, v, shifted), "round");
    const Image truth = load_view_image(v);
    double sum = 0;
    int count = 0;
    for (int y = 0; y < truth.height; ++y)
      for (int x = 0; x < truth.width; ++x)
        if (!in_mask(y, x)) {
          for (int c = 0; c < 3; ++c) sum += std::pow(double(truth.at(y, x, c)) - predicted.at(y, x, c), 2);
          count += 3;
        }
    ASSERT_GT(sum, 0);
    const json& mv = m["views"][i];
    EXPECT_EQ(mv["name"], v.name);
    EXPECT_NEAR(mv["outside_psnr"].get<double>(), psnr_of(sum / count), 1e-3) << v.name;
    EXPECT_LT(mv["outside_ssim"].get<double>(), 0.999);
    EXPECT_FALSE(mv.contains("psnr"));
    EXPECT_FALSE(mv.contains("masked_psnr"));
  }
  EXPECT_TRUE(m["mean"]["outside_psnr"].is_number());
  EXPECT_TRUE(m["mean"]["psnr"].is_null());
  EXPECT_EQ(m["unavailable"]["psnr"],
            "every test view is a held-out view that shows the object (--hold-out-every): see outside_psnr, "
            "outside_ssim");

  // A baseline would fill the very mask that is not compared.
  EvalOptions b = o;
  b.gaussians.reset();
  b.method = EvalMethod::telea;
  EXPECT_EQ(test::error_message([&] { run_evaluation(b); }),
            dir.string() +
                ": --method telea fills the mask of the ground truth itself; held-out views that show the object "
                "(--hold-out-every) compare nothing else");
}

TEST_F(Protocol, InsertionBaselinesOnAnInsertionScene) {
  synth::SynthOptions so;
  so.views = 6;
  so.test_views = 2;
  so.width = 48;
  so.height = 40;
  so.object = synth::ObjectSource::procedural;
  synth::SynthWriteOptions wo;
  wo.task = synth::SynthTask::insert;
  const fs::path dir = test::temp_dir("eval-insert") / "scene";
  synth::write_synth_scene(synth::generate_scene(so, 8), dir, wo);
  EvalOptions o = options("insert-floor");
  o.scene_dir = dir;
  o.height = 40;
  o.method = EvalMethod::floor;
  const json floor = run_evaluation(o);
  EXPECT_EQ(floor["task"], "insert");
  o.method = EvalMethod::sticker;
  EXPECT_EQ(test::error_message([&] { run_evaluation(o); }),
            "--method sticker needs --reference: the reference view with the object painted in");
  o.reference = dir / "reference.png";
  o.out = test::temp_dir("eval-insert-sticker");
  const json sticker = run_evaluation(o);
  EXPECT_EQ(sticker["prediction"]["reference_view"], synth::read_synth_json(dir)["reference"]);
  // The sticker only paints inside the region's projection: outside the test masks it is the floor.
  EXPECT_EQ(floor["views"].size(), 2u);
  EXPECT_NE(sticker["mean"]["masked_psnr"], floor["mean"]["masked_psnr"]);
  // A removal scene has no original/ to compare with.
  EvalOptions r = options("insert-on-removal");
  r.method = EvalMethod::floor;
  EXPECT_EQ(test::error_message([&] { run_evaluation(r); }),
            scene_dir().string() + ": --method floor needs original/ (the test views with nothing inserted, as "
                                   "synth --task insert writes)");
}

TEST(Sticker, SeenFromTheReferenceItIsTheReference) {
  Camera cam;
  cam.K = Intrinsics::from_fov(20, 16, 1.0, 0.8);
  const Image floor(20, 16, 3, 0.25f);
  Image reference(20, 16, 3, 0.75f), region(20, 16, 1), depth(20, 16, 1, 2.f);
  for (int y = 4; y < 10; ++y)
    for (int x = 5; x < 12; ++x) region.at(y, x) = 1;
  const Image out = sticker_view(floor, cam, reference, region, depth, cam);
  EXPECT_EQ(out.at(6, 8, 1), 0.75f);   // inside the region
  EXPECT_EQ(out.at(2, 2, 0), 0.25f);   // far outside it
  EXPECT_EQ(out.at(12, 15, 2), 0.25f);
  depth.at(6, 8) = 0;  // unknown depth: that pixel is not pasted (its neighbours' 2x2 may be)
  EXPECT_EQ(test::error_message([&] { sticker_view(floor, cam, reference, Image(5, 5, 1), depth, cam); }),
            "sticker: the reference's images must be 20x16 (the reference camera), got 5x5");
}

TEST(MeanFill, FillsWithTheRingMean) {
  Image rgb(6, 5, 3, 0.f), mask(6, 5, 1, 0.f);
  mask.at(2, 2) = mask.at(2, 3) = 1;
  for (int x = 0; x < 6; ++x) rgb.at(1, x, 0) = 0.9f;  // row 1 lies in the 1-pixel ring: 4 of its 10 pixels
  const Image out = mean_fill(rgb, mask, 1);
  EXPECT_NEAR(out.at(2, 2, 0), 0.9f * 4 / 10, 1e-6);
  EXPECT_EQ(out.at(2, 2, 1), 0.f);
  EXPECT_EQ(out.at(0, 0, 0), 0.f);
  EXPECT_EQ(out.at(1, 0, 0), 0.9f);  // outside the mask: unchanged
  EXPECT_EQ(test::error_message([&] { mean_fill(rgb, Image(3, 3, 1), 1); }),
            "mean fill: the mask (3x3, 1 channels) does not fit the 6x5 image");
}

TEST(CropAroundMask, SquareCentredOnTheBox) {
  Image mask(100, 60, 1);
  for (int y = 20; y < 30; ++y)
    for (int x = 40; x < 60; ++x) mask.at(y, x) = 1;
  const auto box = crop_around_mask(mask);
  ASSERT_TRUE(box);
  EXPECT_EQ(box->width(), 24);  // 1.2 x 20
  EXPECT_EQ(box->height(), 24);
  EXPECT_EQ(box->x0, 38);
  EXPECT_EQ(box->y0, 13);
  EXPECT_FALSE(crop_around_mask(Image(10, 10, 1)));
}

TEST(Quantize, RoundTruncateNone) {
  Image image(2, 1, 1);
  image.pixels = {0.5f, 1.2f};
  EXPECT_EQ(quantize_image(image, "round").pixels, (std::vector<float>{128 / 255.f, 1.f}));
  EXPECT_EQ(quantize_image(image, "truncate").pixels, (std::vector<float>{127 / 255.f, 1.f}));
  EXPECT_EQ(quantize_image(image, "none").pixels, image.pixels);
  // The image form (on the threads that decode test views, without LibTorch) equals the
  // tensor form bit for bit, over every value near each level.
  torch::manual_seed(5);
  const torch::Tensor values = torch::cat({torch::rand({1, 3, 64, 64}) * 1.2f - 0.1f,
                                           (torch::arange(0, 3 * 64 * 64).reshape({1, 3, 64, 64}) % 256) / 255.0f});
  for (const char* mode : {"round", "truncate"})
    for (int64_t i = 0; i < values.size(0); ++i) {
      const torch::Tensor t = values[i].unsqueeze(0);
      EXPECT_EQ(quantize_image(tensor_to_image(t), mode).pixels, tensor_to_image(quantize_image(t, mode)).pixels)
          << mode;
    }
}

}  // namespace
}  // namespace ii
