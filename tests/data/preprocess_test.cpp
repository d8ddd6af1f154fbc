#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "data/image_ops.h"
#include "data/preprocess.h"
#include "camera/trajectory.h"
#include "data/view_selection.h"
#include "test_support.h"

namespace ii {
namespace {

TEST(Preprocess, OfficialEvaluationSize) {
  // A 16:9 capture at 512 rows is 910 wide, cropped to 904 (official SPIn-NeRF size).
  const WorkingSize s = working_size(1920, 1080, {});
  EXPECT_EQ(s.resized_width, 910);
  EXPECT_EQ(s.width, 904);
  EXPECT_EQ(s.height, 512);
  EXPECT_EQ(s.crop_x, 3);
  const WorkingSize t = working_size(504, 378, {});
  EXPECT_EQ(t.resized_width, 682);  // int(504 * 512 / 378) = 682.67 truncated
  EXPECT_EQ(t.width, 680);
  EXPECT_EQ(t.crop_x, 1);
}

TEST(Preprocess, CameraFollowsResizeAndCropExactly) {
  II_REQUIRE_SHARED(dir, "data/statue");
  const Scene scene = load_scene(dir);
  const PreparedView v = prepare_view(scene.views[0], {});
  EXPECT_EQ(v.rgb.width, 680);
  EXPECT_EQ(v.rgb.height, 512);
  ASSERT_TRUE(v.mask);
  EXPECT_EQ(v.mask->width, 680);
  for (float m : v.mask->pixels) EXPECT_TRUE(m == 0.f || m == 1.f);
  const Intrinsics& K0 = scene.views[0].camera.K;
  const double s = 682.0 / 504.0;
  EXPECT_NEAR(v.camera.K.fx, K0.fx * s, 1e-9);
  EXPECT_NEAR(v.camera.K.cx, 252.0 * s - 1.0, 1e-9);  // centre shifted by the 1-pixel crop
  EXPECT_NEAR(v.camera.K.fy, K0.fy * 512.0 / 378.0, 1e-9);
}

// A reference picture comes at the photo's size, at the working size, or at the official
// evaluation's crop (904x512 of a 1008x567 capture) for a fill working at 256 rows: each gives
// the same working picture of a smooth image, to within the resampling.
TEST(Preprocess, AViewsPictureAtAnyOfItsWorkingSizes) {
  Image photo(1008, 567, 3);
  for (int y = 0; y < photo.height; ++y)
    for (int x = 0; x < photo.width; ++x) {
      photo.at(y, x, 0) = static_cast<float>(x) / 1007.f;
      photo.at(y, x, 1) = static_cast<float>(y) / 566.f;
      photo.at(y, x, 2) = 0.25f;
    }
  const WorkingSize target = working_size(1008, 567, {256, 8});
  const Image want = to_working_size(photo, target);
  const Image eval_crop = to_working_size(photo, working_size(1008, 567, {}));
  ASSERT_EQ(eval_crop.width, 904);
  ASSERT_EQ(eval_crop.height, 512);
  for (const Image* given : std::initializer_list<const Image*>{&photo, &want, &eval_crop}) {
    const auto at = view_picture_at_working_size(*given, 1008, 567, target, 8);
    ASSERT_TRUE(at.has_value()) << given->width << "x" << given->height;
    ASSERT_EQ(at->width, want.width);
    ASSERT_EQ(at->height, want.height);
    float worst = 0;
    for (size_t i = 0; i < want.pixels.size(); ++i) worst = std::max(worst, std::abs(at->pixels[i] - want.pixels[i]));
    EXPECT_LT(worst, 0.01f) << given->width << "x" << given->height;
  }
  EXPECT_FALSE(view_picture_at_working_size(Image(900, 512, 3), 1008, 567, target, 8).has_value());
  EXPECT_FALSE(view_picture_at_working_size(Image(2016, 1100, 3), 1008, 567, target, 8).has_value());
}

TEST(ImageOps, AreaResizeAveragesBlocks) {
  Image img(4, 2, 1);
  img.pixels = {0, 1, 2, 3, 4, 5, 6, 7};
  const Image half = resize_area(img, 2, 1);
  EXPECT_FLOAT_EQ(half.pixels[0], (0 + 1 + 4 + 5) / 4.f);
  EXPECT_FLOAT_EQ(half.pixels[1], (2 + 3 + 6 + 7) / 4.f);
  const Image c = crop(img, 1, 1, 2, 1);
  EXPECT_EQ(c.pixels, (std::vector<float>{5, 6}));
  EXPECT_EQ(test::error_message([&] { crop(img, 3, 0, 2, 1); }),
            "crop 2x1 at (3, 0) is outside the 4x2 image");
}

Scene ring_scene(int n) {
  Scene s;
  for (int k = 0; k < n; ++k) {
    View v;
    v.name = "v" + std::to_string(k);
    const double a = 2 * M_PI * k / (n - 1);
    // centres on a circle, plus one in the middle (index n-1 when odd n is requested)
    v.camera.c2w(0, 3) = (k == n - 1) ? 0.05 : std::cos(a);
    v.camera.c2w(1, 3) = (k == n - 1) ? 0.0 : std::sin(a);
    s.views.push_back(v);
  }
  return s;
}

TEST(ViewSelection, ReferenceInTheMiddleAndALargeTriangle) {
  const Scene s = ring_scene(13);  // 12 on a circle + 1 near the centre
  const std::vector<int> c = select_context_views(s, 4);
  ASSERT_EQ(c.size(), 4u);
  EXPECT_EQ(c[0], 12);
  // The largest triangle on 12 equally spaced points is equilateral: indices 4 apart.
  EXPECT_EQ((c[2] - c[1] + 12) % 12, 4);
  EXPECT_EQ((c[3] - c[2] + 12) % 12, 4);
  EXPECT_EQ(select_context_views(s, 2).size(), 2u);
}

// A capture around its object: 24 cameras on a circle, each looking at its centre. The context is
// the reference's neighbours (looking within 30 degrees of it, at least 3 of them), not views from
// the other sides, which see little of what the reference sees.
TEST(ViewSelection, AroundTheObjectTheContextIsTheReferencesNeighbours) {
  Scene s;
  for (int k = 0; k < 24; ++k) {
    View v;
    v.name = "v" + std::to_string(k);
    const double a = 2 * M_PI * k / 24;
    v.camera.c2w = ::ii::look_at(Eigen::Vector3d(3 * std::cos(a), 0.5, 3 * std::sin(a)), Eigen::Vector3d::Zero(),
                           Eigen::Vector3d::UnitY());
    s.views.push_back(v);
  }
  const std::vector<int> c = select_context_views(s, 4, 6);
  ASSERT_EQ(c.size(), 4u);
  EXPECT_EQ(c[0], 6);
  for (size_t i = 1; i < c.size(); ++i) {
    const int steps = std::min((c[i] - 6 + 24) % 24, (6 - c[i] + 24) % 24);  // 15 degrees each
    EXPECT_LE(steps, 2) << "view " << c[i];
  }
}

TEST(ViewSelection, ByNameWithClearErrors) {
  const Scene s = ring_scene(5);
  EXPECT_EQ(context_views_by_name(s, {"v3", "v0"}), (std::vector<int>{3, 0}));
  EXPECT_EQ(test::error_message([&] { context_views_by_name(s, {"v9"}); }),
            "unknown context view 'v9' (views: v0, v1, v2, v3, v4)");
  EXPECT_EQ(test::error_message([&] { context_views_by_name(s, {"v1", "v1"}); }),
            "context view 'v1' is listed twice");
  EXPECT_EQ(test::error_message([&] { select_context_views(s, 6); }),
            "the scene has 5 views, 6 context views are needed");
}

}  // namespace
}  // namespace ii
