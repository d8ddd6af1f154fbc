// Floaters: two views of a wall, the first with a small square of "flying pixels" 40 % nearer
// than the wall. The square's Gaussians hang in front of what the second view sees and are faded;
// the wall's, on or off the square's depth edge, are not; nothing is faded where the second
// view's mask hides its depth, nor with a fade of 1; a prediction records them.
#include <gtest/gtest.h>

#include <cmath>

#include "camera/trajectory.h"
#include "data/scene.h"
#include "model/default_model.h"
#include "geometry/floaters.h"
#include "model/model_input.h"
#include "predict/predictor.h"
#include "synthetic_room.h"
#include "test_support.h"

namespace ii {
namespace {
// A namespace of its own: the folder's test files are compiled together (CMake's unity build).
namespace floaters_test {

constexpr int kW = 16, kH = 12, kViews = 2;
constexpr int kTop = 5, kLeft = 7, kSize = 2;  // the flying square in the first view

struct Wall {
  std::vector<Camera> cameras;
  std::vector<PreparedView> views;
  GaussianMaps maps;
};

// The wall z = 0 seen by two cameras 0.6 apart; the first view's square 40 % nearer.
Wall wall() {
  Wall s;
  for (int v = 0; v < kViews; ++v) {
    Camera c;
    c.K = Intrinsics::from_fov(kW, kH, 50 * M_PI / 180, 2 * std::atan(std::tan(25 * M_PI / 180) * kH / kW));
    c.c2w = look_at({-0.3 + 0.6 * v, 0.1, 3}, {0, 0, 0}, {0, 1, 0});
    s.cameras.push_back(c);
    PreparedView view;
    view.name = "view_" + std::to_string(v);
    view.rgb = Image(kW, kH, 3, 0.5f);
    view.camera = c;
    s.views.push_back(view);
  }
  torch::Tensor rays_o, rays_d, rays_d_un, plucker;
  compute_ray_tensors(s.cameras, rays_o, rays_d, rays_d_un, plucker);
  // z-depth to the plane z = 0 along each pixel's ray: rays_d_un has camera depth 1.
  torch::Tensor depth = -rays_o.select(3, 2) / rays_d_un.select(3, 2);  // (V, H, W)
  depth[0].slice(0, kTop, kTop + kSize).slice(1, kLeft, kLeft + kSize).mul_(0.6);
  s.maps.depth = depth.unsqueeze(1).unsqueeze(0).contiguous();  // (1, V, 1, H, W)
  s.maps.xyz = (rays_o + depth.unsqueeze(3) * rays_d_un).permute({0, 3, 1, 2}).unsqueeze(0).contiguous();
  s.maps.opacity = torch::full({1, kViews, 1, kH, kW}, 0.5f);
  return s;
}

torch::Tensor square() {
  torch::Tensor m = torch::zeros({kH, kW}, torch::kBool);
  m.slice(0, kTop, kTop + kSize).slice(1, kLeft, kLeft + kSize).fill_(true);
  return m;
}

TEST(Floaters, TheSquareInFrontOfTheOtherViewsWallIsFadedAndTheWallIsNot) {
  Wall s = wall();
  FloaterOptions options;
  EXPECT_EQ(fade_floaters(s.maps, s.views, s.cameras, options), kSize * kSize);
  const torch::Tensor first = s.maps.opacity[0][0][0];
  EXPECT_TRUE(torch::allclose(first.index({square()}), torch::full({kSize * kSize}, 0.15f)));
  EXPECT_TRUE(torch::equal(first.index({square().logical_not()}), torch::full({kH * kW - kSize * kSize}, 0.5f)))
      << "the wall around the square is on its depth edge but behind nothing";
  EXPECT_TRUE(torch::equal(s.maps.opacity[0][1][0], torch::full({kH, kW}, 0.5f))) << "the second view has no edge";
}

TEST(Floaters, NothingFadedWhereTheOtherViewsMaskHidesItsDepthOrWithAFadeOfOne) {
  Wall masked = wall();
  masked.views[1].mask = Image(kW, kH, 1, 1.f);  // the second view's depth is all a guess
  EXPECT_EQ(fade_floaters(masked.maps, masked.views, masked.cameras, {}), 0);
  Wall off = wall();
  FloaterOptions none;
  none.fade = 1;
  EXPECT_EQ(fade_floaters(off.maps, off.views, off.cameras, none), 0);
  EXPECT_TRUE(torch::equal(off.maps.opacity, torch::full({1, kViews, 1, kH, kW}, 0.5f)));
  Wall wrong = wall();
  wrong.cameras.pop_back();
  EXPECT_EQ(test::error_message([&] { fade_floaters(wrong.maps, wrong.views, wrong.cameras, {}); }),
            "floaters: 2 views and 1 cameras for 2 views of maps");
  Wall small_mask = wall();
  small_mask.views[1].mask = Image(kW - 1, kH, 1);
  EXPECT_EQ(test::error_message([&] { fade_floaters(small_mask.maps, small_mask.views, small_mask.cameras, {}); }),
            "visibility: view view_1's mask is 15x12, its depth 16x12");
}

TEST(Floaters, APredictionRecordsThem) {
  if (!has_default_model()) GTEST_SKIP() << "this build has no default model";
  const std::filesystem::path dir = test::synthetic_room("floaters", 4, 64, 8);
  const Scene scene = load_scene(dir);
  const Predictor predictor("", torch::kCPU, Precision::Float32);
  SceneInputOptions options;
  options.preprocess.height = 64;
  const Prediction faded = predictor.predict(scene, options);
  options.geometry.floaters.fade = 1;
  const Prediction kept = predictor.predict(scene, options);
  const nlohmann::json recorded = faded.describe_geometry()["floaters"];
  EXPECT_EQ(recorded["fade"], 0.3);
  EXPECT_GT(recorded["faded"].get<int64_t>(), 0);
  EXPECT_EQ(kept.describe_geometry()["floaters"]["faded"], 0);
  // Only opacities change, and only those recorded, each to 0.3 of what it was.
  EXPECT_TRUE(torch::equal(faded.maps().xyz, kept.maps().xyz));
  const torch::Tensor changed = faded.maps().opacity.ne(kept.maps().opacity);
  EXPECT_EQ(changed.sum().item<int64_t>(), recorded["faded"].get<int64_t>());
  EXPECT_TRUE(torch::allclose(faded.maps().opacity.index({changed}), kept.maps().opacity.index({changed}) * 0.3));
}

}  // namespace floaters_test
}  // namespace
}  // namespace ii
