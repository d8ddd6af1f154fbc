// From a real scene to network inputs, and the errors a user of `infer` can run into.
#include <gtest/gtest.h>

#include "data/scene.h"
#include "model/inference.h"
#include "model/scene_input.h"
#include "test_support.h"

namespace ii {
namespace {

namespace fs = std::filesystem;

// Four of the statue's views, IMG_2720 the reference, at `height` rows.
InputOptions statue_context(int height) {
  InputOptions opts;
  opts.context = {"IMG_2720", "IMG_2707", "IMG_2715", "IMG_2730"};
  opts.preprocess.height = height;
  return opts;
}

TEST(SceneInput, StatueBuildsOfficialInputs) {
  II_REQUIRE_SHARED(dir, "data/statue");
  const Scene scene = load_scene(dir);
  const InputOptions opts = statue_context(128);
  const SceneInput si = prepare_scene_input(scene, opts);
  ASSERT_EQ(si.input.images.sizes(), (std::vector<int64_t>{4, 4, 128, 168}));
  EXPECT_EQ(si.reference_source, "ns");
  // Reference: mask channel zero; others: grey (0.0) wherever the mask is set.
  EXPECT_EQ(si.input.images[0][3].abs().sum().item<float>(), 0.f);
  const auto mask = si.input.images[1][3];
  EXPECT_GT(mask.sum().item<float>(), 0.f);
  const auto rgb_in_mask = (si.input.images[1].narrow(0, 0, 3) * mask).abs().max().item<float>();
  EXPECT_EQ(rgb_in_mask, 0.f);
  // Normalised camera centres lie in [-1, 1].
  EXPECT_LE(si.input.rays_o.abs().max().item<float>(), 1.0f + 1e-6f);
}

// What a server reuses between edits gives the inputs a fresh read gives: views prepared once
// (PreparedViewCache), the classical reference made ahead, the rays of a camera set kept.
TEST(SceneInput, CachedViewsAndAReferenceMadeAheadGiveTheSameInput) {
  II_REQUIRE_SHARED(dir, "data/statue");
  const Scene scene = load_scene(dir);
  const InputOptions opts = statue_context(64);
  const SceneInput fresh = prepare_scene_input(scene, opts);

  PreparedViewCache cache;
  InputOptions cached = opts;
  cached.view_cache = &cache;
  const Image region = *load_view_mask(*scene.find("IMG_2720"));
  cached.reference_image = painted_reference(scene, "IMG_2720", region, cached);
  cached.reference_image_source = "ns";
  for (int run = 0; run < 2; ++run) {  // the second from the cache alone
    const SceneInput again = prepare_scene_input(scene, cached);
    EXPECT_EQ(again.reference_source, "ns");
    const std::vector<torch::Tensor> got = {again.input.images, again.input.plucker, again.input.rays_o,
                                            again.input.rays_d_un},
                                     want = {fresh.input.images, fresh.input.plucker, fresh.input.rays_o,
                                             fresh.input.rays_d_un};
    for (size_t i = 0; i < got.size(); ++i) EXPECT_TRUE(torch::equal(got[i], want[i])) << i << " on run " << run;
  }
  // The cache holds what prepare_view makes.
  const PreparedView direct = prepare_view(*scene.find("IMG_2715"), opts.preprocess);
  const PreparedView kept = cache.get(*scene.find("IMG_2715"), opts.preprocess);
  EXPECT_EQ(kept.rgb.pixels, direct.rgb.pixels);
  ASSERT_TRUE(kept.mask && direct.mask);
  EXPECT_EQ(kept.mask->pixels, direct.mask->pixels);
}

// The region the 2D inpainter paints is the mask grown by inpaint_grow of the larger side (at
// least a pixel); the network's mask input stays the mask; unset or 0, the mask as it is.
TEST(SceneInput, TheInpaintersRegionIsTheMaskGrown) {
  Image mask(100, 60, 1);
  mask.at(30, 50) = 1.f;
  auto count = [](const Image& m) { return std::count_if(m.pixels.begin(), m.pixels.end(), [](float v) { return v > 0.5f; }); };
  EXPECT_EQ(count(region_to_paint(mask, 0)), 1);
  const Image grown = region_to_paint(mask, 0.02);  // 2 pixels of 100: a 5 x 5 square
  EXPECT_EQ(count(grown), 25);
  EXPECT_EQ(grown.at(28, 48), 1.f);
  EXPECT_EQ(grown.at(27, 50), 0.f);
  EXPECT_EQ(count(region_to_paint(mask, 0.001)), 9);  // at least a pixel

  II_REQUIRE_SHARED(dir, "data/statue");
  const Scene scene = load_scene(dir);
  InputOptions opts = statue_context(64);
  const SceneInput plain = prepare_scene_input(scene, opts);
  opts.inpaint_grow = 0.03;
  const SceneInput wider = prepare_scene_input(scene, opts);
  EXPECT_EQ(plain.reference_inpainter["grow"], 0.0);
  EXPECT_EQ(wider.reference_inpainter["grow"], 0.03);
  // The reference's picture differs just outside the mask, the network's mask input not at all.
  EXPECT_FALSE(torch::equal(plain.input.images[0].narrow(0, 0, 3), wider.input.images[0].narrow(0, 0, 3)));
  EXPECT_TRUE(torch::equal(plain.input.images.narrow(1, 3, 1), wider.input.images.narrow(1, 3, 1)));
  EXPECT_TRUE(torch::equal(plain.input.images.narrow(0, 1, 3), wider.input.images.narrow(0, 1, 3)));
}

TEST(SceneInput, KeepObjectFeedsThePhotosUnmasked) {
  II_REQUIRE_SHARED(dir, "data/statue");
  Scene scene = load_scene(dir);
  for (View& v : scene.views) v.mask_path.reset();  // no masks needed
  InputOptions opts;
  opts.context = {"IMG_2720", "IMG_2707"};
  opts.preprocess.height = 64;
  opts.keep_object = true;
  const SceneInput si = prepare_scene_input(scene, opts);
  EXPECT_EQ(si.reference_source, "photo (object kept)");
  EXPECT_EQ(si.input.images.narrow(1, 3, 1).abs().sum().item<float>(), 0.f);  // every mask channel zero
  const PreparedView photo = prepare_view(*scene.find("IMG_2707"), opts.preprocess);
  const torch::Tensor expected = torch::from_blob(const_cast<float*>(photo.rgb.pixels.data()), {64, 80, 3})
                                     .permute({2, 0, 1}) * 2.0 - 1.0;
  EXPECT_LT((si.input.images[1].narrow(0, 0, 3) - expected).abs().max().item<float>(), 1e-6f);
}

TEST(SceneInput, UserErrorsAreClear) {
  II_REQUIRE_SHARED(dir, "data/statue");
  const Scene scene = load_scene(dir);
  InputOptions opts;
  opts.preprocess.height = 64;
  opts.context = {"IMG_2720", "IMG_9999"};
  EXPECT_EQ(test::error_message([&] { prepare_scene_input(scene, opts); }).rfind("unknown context view 'IMG_9999' (views: IMG_2707, ", 0), 0u);

  const fs::path ref = test::temp_dir("ref") / "ref.png";
  write_png(ref, Image(100, 50, 3, 0.5f));
  opts.context = {"IMG_2720", "IMG_2707"};
  opts.reference = ref;
  EXPECT_EQ(test::error_message([&] { prepare_scene_input(scene, opts); }),
            ref.string() + ": reference image is 100x50, but view IMG_2720 is 504x378 (working size 80x64): give the "
                           "inpainted image at either size");

  Scene no_masks = scene;
  for (View& v : no_masks.views) v.mask_path.reset();
  opts.reference.reset();
  EXPECT_EQ(test::error_message([&] { prepare_scene_input(no_masks, opts); }),
            "view IMG_2707 has no object mask: give masks for every context view (--masks DIR or --alpha-masks)");
}

TEST(SceneInput, ModelMustFitTheInput) {
  ModelInput in;
  in.images = torch::zeros({4, 4, 64, 72});
  ModelConfig rgb_only = ModelConfig::from_preset("tiny");
  rgb_only.image_channels = 3;
  EXPECT_EQ(test::error_message([&] { check_model_fits_input(rgb_only, in, "stage1.pth"); }),
            "stage1.pth: this is an RGB-only (stage-1 reconstruction) model; inpainting needs a model with the mask "
            "channel (4 input channels)");
  ModelConfig p16 = ModelConfig::from_preset("tiny");
  p16.patch = 16;
  EXPECT_EQ(test::error_message([&] { check_model_fits_input(p16, in, "m.safetensors"); }),
            "m.safetensors: patch size 16 does not divide the working size 72x64; choose --height as a multiple of 16");
}

}  // namespace
}  // namespace ii
