#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include <Eigen/LU>

#include "data/scene.h"
#include "data/scene_readers.h"
#include "io/npy.h"
#include "test_support.h"

namespace ii {
namespace {

namespace fs = std::filesystem;

TEST(LlffScene, StatueReadsViewsMasksAndIntrinsics) {
  II_REQUIRE_SHARED(dir, "data/statue");
  const Scene s = load_scene(dir);
  EXPECT_EQ(s.format, "llff");
  ASSERT_EQ(s.views.size(), 29u);
  EXPECT_TRUE(s.test_views.empty());
  EXPECT_TRUE(s.has_masks());
  EXPECT_EQ(s.views.front().name, "IMG_2707");
  EXPECT_EQ(s.views.back().name, "IMG_2736");
  const Intrinsics& K = s.views[0].camera.K;
  EXPECT_EQ(K.width, 504);
  EXPECT_EQ(K.height, 378);
  EXPECT_NEAR(K.fx, 740.325 / 2, 0.01);  // hwf focal is for the 1008-wide level
  EXPECT_DOUBLE_EQ(K.cx, 252.0);
  ASSERT_TRUE(s.near && s.far);
  EXPECT_NEAR(*s.near, 26.0, 0.1);
  // Rotation is a proper rotation after the LLFF -> OpenGL column swap.
  EXPECT_NEAR(s.views[3].camera.rotation().determinant(), 1.0, 1e-6);
  const auto mask = load_view_mask(s.views[0]);
  ASSERT_TRUE(mask.has_value());
  double coverage = 0;
  for (float v : mask->pixels) coverage += v;
  coverage /= mask->pixels.size();
  EXPECT_GT(coverage, 0.07);  // 7.7-9.7 % of pixels are statue (PROVENANCE.md)
  EXPECT_LT(coverage, 0.10);
}

TEST(LlffScene, HoldOutEveryNthViewAsATestViewThatShowsTheObject) {
  II_REQUIRE_SHARED(dir, "data/statue");
  SceneOptions o;
  o.hold_out_every = 8;
  const Scene s = load_scene(dir, o);
  // Views 0, 8, 16, 24 of 29 (3DGS's LLFF hold-out).
  ASSERT_EQ(s.test_views.size(), 4u);
  ASSERT_EQ(s.views.size(), 25u);
  EXPECT_EQ(s.test_views[0].name, "IMG_2707");
  EXPECT_EQ(s.test_views[1].name, "IMG_2715");
  for (const View& v : s.test_views) EXPECT_TRUE(v.shows_object && v.mask_path) << v.name;
  for (const View& v : s.views) EXPECT_FALSE(v.shows_object) << v.name;
  EXPECT_EQ(s.views.front().name, "IMG_2708");
  EXPECT_NE(std::find(s.notes.begin(), s.notes.end(), "4 of 29 views held out as test views (one in 8)"),
            s.notes.end());

  // Held-out views need masks: fern has none.
  II_REQUIRE_SHARED(fern, "data/fern");
  EXPECT_EQ(test::error_message([&] { load_scene(fern, o); }),
            fern.string() + ": view " + load_scene(fern).views[0].name +
                " has no object mask; a held-out view is compared outside its mask (or evaluate a reconstruction with "
            "--keep-object)");
  // A reconstruction's held-out views need none: compared whole.
  o.hold_out_whole = true;
  const Scene held = load_scene(fern, o);
  ASSERT_FALSE(held.test_views.empty());
  EXPECT_FALSE(held.test_views[0].shows_object);
  EXPECT_FALSE(held.test_views[0].mask_path.has_value());
}

TEST(LlffScene, FernHasNoMasks) {
  II_REQUIRE_SHARED(dir, "data/fern");
  const Scene s = load_scene(dir);
  ASSERT_EQ(s.views.size(), 20u);
  EXPECT_FALSE(s.has_masks());
  EXPECT_NEAR(s.views[0].camera.K.fx, 3260.53 / 8, 0.01);
  EXPECT_FALSE(load_view_mask(s.views[0]).has_value());
}

// A SPIn-NeRF-layout scene in a temporary folder: n images, the first `tests` of them
// object-free test views with masks in test_label/, the rest masked by label/.
struct SyntheticLlff {
  fs::path dir;
  explicit SyntheticLlff(int n, int tests, int label_count = -1, int mask_width = 16) {
    dir = test::temp_dir("llff");
    std::vector<double> rows;
    for (int k = 0; k < n; ++k) {
      // identity LLFF rotation columns (down, right, back), centre moving along x
      const double m[15] = {1, 0, 0, double(k), 24, 0, 1, 0, 0, 32, 0, 0, 1, 0, 20};
      rows.insert(rows.end(), m, m + 15);
      rows.push_back(1.0);
      rows.push_back(10.0);
    }
    write_npy(dir / "poses_bounds.npy", rows, {n, 17});
    fs::create_directories(dir / "images_2" / "label");
    fs::create_directories(dir / "images_2" / "test_label");
    if (label_count < 0) label_count = n - tests;
    for (int k = 0; k < n; ++k) {
      const std::string name = fmt::format("img{:02d}.png", k);
      write_png(dir / "images_2" / name, Image(16, 12, 3, 0.5f));
      Image mask(mask_width, 12, 1, 0.f);
      mask.at(5, 5) = 1.f;
      if (k < tests) write_png(dir / "images_2" / "test_label" / name, mask);
      else if (k - tests < label_count) write_png(dir / "images_2" / "label" / name, mask);
    }
  }
};

TEST(LlffScene, SpinNerfLayoutSplitsTestViews) {
  const SyntheticLlff scene(6, 2);
  const Scene s = load_scene(scene.dir);
  ASSERT_EQ(s.test_views.size(), 2u);
  ASSERT_EQ(s.views.size(), 4u);
  EXPECT_EQ(s.test_views[0].name, "img00");
  EXPECT_EQ(s.views[0].name, "img02");
  EXPECT_TRUE(s.has_masks());
  EXPECT_TRUE(s.test_views[1].mask_path->string().find("test_label") != std::string::npos);
  // Image 16x12 of a 32x24 full-resolution level: focal halves.
  EXPECT_DOUBLE_EQ(s.views[0].camera.K.fx, 10.0);
  // LLFF (down, right, back) identity -> OpenGL columns (right, up, back) = (e1, -e0, e2).
  EXPECT_DOUBLE_EQ(s.views[0].camera.c2w(1, 0), 1.0);
  EXPECT_DOUBLE_EQ(s.views[0].camera.c2w(0, 1), -1.0);
  EXPECT_DOUBLE_EQ(s.views[2].camera.center().x(), 4.0);
}

// SPIn-NeRF as distributed: test masks named out_00001.png ... instead of after their
// images. Built from the statue scene: its first 4 views become test views.
TEST(LlffScene, NumberedTestMasksPairWithTestViewsByOrder) {
  II_REQUIRE_SHARED(statue, "data/statue");
  const fs::path dir = test::temp_dir("spinnerf");
  fs::create_symlink(statue / "poses_bounds.npy", dir / "poses_bounds.npy");
  const fs::path images = dir / "images_2";
  fs::create_directories(images / "label");
  fs::create_directories(images / "test_label");
  std::vector<fs::path> sources;
  for (const auto& e : fs::directory_iterator(statue / "images_2"))
    if (e.path().extension() == ".png") sources.push_back(e.path());
  std::sort(sources.begin(), sources.end());
  ASSERT_EQ(sources.size(), 29u);
  const int tests = 4;
  for (int k = 0; k < 29; ++k) {
    const fs::path& image = sources[k];
    fs::create_symlink(image, images / image.filename());
    const fs::path mask = statue / "images_2" / "label" / image.filename();
    fs::create_symlink(mask, k < tests ? images / "test_label" / fmt::format("out_{:05d}.png", k + 1)
                                       : images / "label" / image.filename());
  }
  const Scene s = load_scene(dir);
  ASSERT_EQ(s.test_views.size(), 4u);
  ASSERT_EQ(s.views.size(), 25u);
  for (int k = 0; k < tests; ++k) {
    EXPECT_EQ(s.test_views[k].name, sources[k].stem().string());
    EXPECT_EQ(s.test_views[k].mask_path->filename(), fmt::format("out_{:05d}.png", k + 1));
  }
  EXPECT_EQ(s.views[0].mask_path->filename(), "IMG_2711.png");
  EXPECT_EQ(s.notes, std::vector<std::string>{(images / "test_label").string() +
                                              ": 4 masks are named after no image; paired with the first 4 images "
                                              "in name order (out_00001.png -> IMG_2707.png, ...)"});
  // The mask really is the view's: same pixels as the statue's own mask of that image.
  EXPECT_EQ(load_view_mask(s.test_views[2])->pixels,
            read_mask(statue / "images_2" / "label" / sources[2].filename()).pixels);

  // Counts that disagree: 4 numbered test masks, 24 training masks, 29 images.
  fs::remove(images / "label" / "IMG_2736.png");
  EXPECT_EQ(test::error_message([&] { load_scene(dir); }),
            (images / "test_label").string() +
                ": 4 masks are named after no image and cannot be paired with images by order: label/ has 24 "
                "masks, and 4 + 24 is not the scene's 29 images");
}

TEST(LlffScene, SlightlyOffSizeMaskIsResized) {
  const SyntheticLlff scene(3, 0, -1, /*mask_width=*/17);
  const Scene s = load_scene(scene.dir);
  const auto mask = load_view_mask(s.views[0]);
  ASSERT_TRUE(mask);
  EXPECT_EQ(mask->width, 16);
  EXPECT_EQ(mask->height, 12);
}

TEST(LlffScene, BadInputIsAClearError) {
  {
    const SyntheticLlff scene(5, 1, /*label_count=*/2);
    EXPECT_EQ(test::error_message([&] { load_scene(scene.dir); }),
              (scene.dir / "images_2" / "label").string() + ": has 2 masks for 4 training views");
  }
  {
    const SyntheticLlff scene(3, 0);
    fs::remove(scene.dir / "images_2" / "img01.png");
    EXPECT_EQ(test::error_message([&] { load_scene(scene.dir); }),
              (scene.dir / "images_2").string() + ": holds 2 images but poses_bounds.npy has 3 poses");
  }
  {
    const SyntheticLlff scene(3, 0);
    std::vector<double> rows(3 * 17, 1.0);
    rows[20] = std::nan("");
    write_npy(scene.dir / "poses_bounds.npy", rows, {3, 17});
    EXPECT_EQ(test::error_message([&] { load_scene(scene.dir); }),
              (scene.dir / "poses_bounds.npy").string() + ": contains NaN or infinite values");
    write_npy(scene.dir / "poses_bounds.npy", std::vector<double>(3 * 15, 1.0), {3, 15});
    EXPECT_EQ(test::error_message([&] { load_scene(scene.dir); }),
              (scene.dir / "poses_bounds.npy").string() + ": expected an N x 17 array, got shape 3 x 15");
  }
  {
    const SyntheticLlff scene(3, 0, -1, /*mask_width=*/40);
    const Scene s = load_scene(scene.dir);
    EXPECT_EQ(test::error_message([&] { load_view_mask(s.views[0]); }),
              s.views[0].mask_path->string() + ": mask is 40x12 but its image is 16x12");
  }
  const fs::path empty = test::temp_dir("empty");
  EXPECT_EQ(test::error_message([&] { load_scene(empty); }),
            empty.string() + ": cannot tell the scene format: expected poses_bounds.npy (LLFF), "
                             "transforms.json (nerfstudio) or a COLMAP model (sparse/0/cameras.bin)");
  EXPECT_EQ(test::error_message([&] { load_scene(empty / "nope"); }),
            (empty / "nope").string() + ": scene folder not found");
}

TEST(SceneMasks, MaskFolderMatchesByStemOrColmapName) {
  const SyntheticLlff scene(3, 0);
  const fs::path masks = test::temp_dir("masks");
  Image m(16, 12, 1, 0.f);
  write_png(masks / "img00.png", m);      // same stem
  write_png(masks / "img01.png.png", m);  // COLMAP's "<image file name>.png"
  SceneOptions opts;
  opts.mask_dir = masks;
  const Scene s = load_scene(scene.dir, opts);
  EXPECT_EQ(s.views[0].mask_path->filename(), "img00.png");
  EXPECT_EQ(s.views[1].mask_path->filename(), "img01.png.png");
  // img02 keeps the mask from label/.
  EXPECT_TRUE(s.views[2].mask_path->string().find("label") != std::string::npos);
}

TEST(SceneMasks, AlphaChannelMarksTheObject) {
  const SyntheticLlff scene(2, 0);
  Image rgba(16, 12, 4, 1.f);
  rgba.at(3, 4, 3) = 0.f;  // transparent pixel = object
  write_png(scene.dir / "images_2" / "img00.png", rgba);
  SceneOptions opts;
  opts.alpha_masks = true;
  const Scene s = load_scene(scene.dir, opts);
  const auto mask = load_view_mask(s.views[0]);
  ASSERT_TRUE(mask);
  EXPECT_EQ(mask->at(3, 4), 1.f);
  EXPECT_EQ(mask->at(0, 0), 0.f);
  EXPECT_EQ(test::error_message([&] { load_view_mask(s.views[1]); }),
            s.views[1].image_path.string() + ": has no alpha channel to take the object mask from");
}

}  // namespace
}  // namespace ii
