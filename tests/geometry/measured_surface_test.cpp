// The surface a depth map measured: a prediction on a synthetic room (which has depth maps) puts
// each context view's Gaussians outside its mask (grown by the margin) at the map's depth, flat and
// opaque, leaves those in and beside the mask as the network made them, records what it did, and
// gives each view's own picture back more closely; nothing without depth maps, with opacity 0 or
// with --align-depth none.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>

#include "data/masks.h"
#include "data/scene.h"
#include "eval/metrics.h"
#include "gaussians/gaussians.h"
#include "model/default_model.h"
#include "geometry/flying_pixels.h"
#include "predict/predictor.h"
#include "render/rasterizer.h"
#include "synthetic_room.h"
#include "tensor/camera_projection.h"
#include "tensor/image_tensor.h"
#include "test_support.h"

namespace ii {
namespace {

#define II_REQUIRE_DEFAULT_MODEL() \
  if (!has_default_model()) GTEST_SKIP() << "this build has no default model"

SceneInputOptions at_64_rows() {
  SceneInputOptions options;
  options.preprocess.height = 64;
  options.geometry.floaters.fade = 1;  // the opacities as this step leaves them
  return options;
}

// Outside the view's mask grown by `margin` pixels (as the step takes its pixels), (H, W) bool.
torch::Tensor away_from_mask(const PreparedView& view, int margin) {
  if (!view.mask) return torch::ones({view.rgb.height, view.rgb.width}, torch::kBool);
  const torch::Tensor mask = image_to_tensor(*view.mask);  // (1, 1, H, W)
  return torch::max_pool2d(mask, {2 * margin + 1, 2 * margin + 1}, {1, 1}, {margin, margin})[0][0].le(0.5);
}

// PSNR of each view's own pixel rows rendered at its camera against its picture, outside its mask.
double own_view_psnr(const Prediction& p, size_t v) {
  const int64_t h = p.maps().depth.size(3), w = p.maps().depth.size(4);
  const GaussianSet all = gaussians_from_maps(narrowed(p.maps(), 1, static_cast<int64_t>(v)));
  RenderCamera camera;
  camera.camera = p.input.input.view_cameras[v];
  const torch::Tensor rendered = render(all, camera).rgb.permute({2, 0, 1}).unsqueeze(0);
  const PreparedView& view = p.input.views[v];
  const torch::Tensor outside = away_from_mask(view, 0).to(torch::kFloat32).view({1, 1, h, w});
  return masked_psnr(rendered, image_to_tensor(view.rgb), outside)[0].item<double>();
}

TEST(MeasuredSurface, PutsTheGaussiansOutsideTheMaskOnTheMeasuredDepth) {
  II_REQUIRE_DEFAULT_MODEL();
  const std::filesystem::path dir = test::synthetic_room("measured-surface", 4, 64, 21);
  const Scene scene = load_scene(dir);
  const Predictor predictor("", torch::kCPU, Precision::Float32);
  SceneInputOptions options = at_64_rows();
  options.geometry.measured_surface.beside_object = false;  // (the next test: inside the masks)
  options.geometry.region_surface.opacity = 0;  // (the reference's region: region_surface_test.cpp)
  const Prediction with = predictor.predict(scene, options);
  options.geometry.measured_surface.opacity = 0;
  const Prediction without = predictor.predict(scene, options);

  const nlohmann::json record = with.describe_geometry()["measured_surface"];
  ASSERT_EQ(record["views"].size(), 4u);
  EXPECT_EQ(record["opacity"], 0.95);
  EXPECT_EQ(without.describe_geometry()["measured_surface"]["views"].size(), 0u);
  int64_t taken = 0, moved = 0;
  for (size_t v = 0; v < 4; ++v) {
    const PreparedView& view = with.input.views[v];
    EXPECT_EQ(record["views"][v], view.name);
    const Image map = *load_view_depth(scene, scene.views[static_cast<size_t>(with.input.context[v])]);
    ASSERT_EQ(map.width, 64);  // the room is made at the working size: no resampling to follow
    // Its flying pixels (the room's depth is a mean over each pixel) on their far side.
    const FarSide far = flying_pixels_to_far_side(image_to_tensor(map)[0][0], FlyingPixelOptions());
    moved += far.moved.sum().item<int64_t>();
    const torch::Tensor measured = far.depth / with.input.normalization.scale;
    const torch::Tensor take = away_from_mask(view, 1).logical_and(measured.gt(0));
    const int64_t vi = static_cast<int64_t>(v);
    taken += take.sum().item<int64_t>();
    // On the measured depth, opaque, flat (the third axis a tenth of the narrower one or less).
    const torch::Tensor depth = with.maps().depth[0][vi][0];
    EXPECT_TRUE(torch::allclose(depth.index({take}), measured.index({take}), 1e-5, 1e-6));
    EXPECT_GE(with.maps().opacity[0][vi][0].index({take}).min().item<float>(), 0.95f);
    const torch::Tensor scales = with.maps().scale[0][vi].permute({1, 2, 0}).index({take});  // (N, 3)
    EXPECT_TRUE(scales.select(1, 2).le(0.1001 * std::get<0>(scales.narrow(1, 0, 2).min(1))).all().item<bool>());
    // In and beside the mask: the network's Gaussians, untouched.
    const torch::Tensor kept = take.logical_not();
    for (auto member : {&GaussianMaps::xyz, &GaussianMaps::scale, &GaussianMaps::opacity, &GaussianMaps::rotation}) {
      const torch::Tensor a = (with.maps().*member)[0][vi].permute({1, 2, 0}).index({kept});
      const torch::Tensor b = (without.maps().*member)[0][vi].permute({1, 2, 0}).index({kept});
      EXPECT_TRUE(torch::equal(a, b));
    }
    // The view's own Gaussians give its picture back more closely.
    EXPECT_GT(own_view_psnr(with, v), own_view_psnr(without, v) + 1) << view.name;
  }
  EXPECT_EQ(record["gaussians"], taken);
  EXPECT_GT(taken, 4 * 64 * 64 / 2);
  EXPECT_GT(moved, 0);
  EXPECT_EQ(record["far_side"], moved);
}

// A mask propagated from one view is wider than the object: inside the other views' masks, what
// lies outside the cone of the reference's mask is the scene beside the object and goes on the
// measured surface in the photo's colours (its margin's too); the object's own pixels that the
// reference sees stay the network's.
TEST(MeasuredSurface, TheSceneBesideTheObjectInsideAWideMask) {
  II_REQUIRE_DEFAULT_MODEL();
  const std::filesystem::path dir = test::synthetic_room("measured-surface-wide", 4, 64, 23);
  const Scene scene = load_scene(dir);
  const Predictor predictor("", torch::kCPU, Precision::Float32);
  SceneInputOptions options = at_64_rows();
  std::map<std::string, torch::Tensor> object;  // each view's object, (H, W) bool
  for (const View& view : scene.views) {
    const std::optional<Image> mask = load_view_mask(view);
    if (!mask) continue;
    const torch::Tensor m = image_to_tensor(*mask);  // (1, 1, H, W)
    // Its rim eroded by a pixel: there the room's depth map may already hold what is behind.
    object[view.name] = torch::max_pool2d(1 - m, {3, 3}, {1, 1}, {1, 1})[0][0].lt(0.5);
    Image wide = *mask;  // grown by 8 pixels
    const torch::Tensor grown = torch::max_pool2d(m, {17, 17}, {1, 1}, {8, 8}).contiguous();
    std::copy(grown.data_ptr<float>(), grown.data_ptr<float>() + grown.numel(), wide.pixels.begin());
    options.masks[view.name] = wide;
  }
  const Prediction with = predictor.predict(scene, options);
  options.geometry.measured_surface.beside_object = false;
  const Prediction without = predictor.predict(scene, options);
  const nlohmann::json record = with.describe_geometry()["measured_surface"];
  EXPECT_EQ(without.describe_geometry()["measured_surface"]["beside_object"], 0);
  int64_t beside = 0;
  for (size_t v = 1; v < 4; ++v) {
    const PreparedView& view = with.input.views[v];
    const int64_t vi = static_cast<int64_t>(v);
    const torch::Tensor changed =
        with.maps().xyz[0][vi].ne(without.maps().xyz[0][vi]).any(0).logical_or(
            with.maps().rgb[0][vi].ne(without.maps().rgb[0][vi]).any(0));
    beside += changed.sum().item<int64_t>();
    // Only inside the wide mask and its margin.
    EXPECT_FALSE(changed.logical_and(away_from_mask(view, MeasuredSurfaceOptions().mask_margin)).any().item<bool>())
        << view.name;
    // The object's own pixels that the reference's picture holds (what it does not see, it
    // cannot remove) stay the network's: their points lie in the reference's mask's cone.
    const PixelHit hit = project(with.input.input.view_cameras.front(), with.maps().xyz[0][vi].flatten(1).t());
    const torch::Tensor seen_by_reference = hit.inside.view({64, 64});
    EXPECT_FALSE(changed.logical_and(object.at(view.name)).logical_and(seen_by_reference).any().item<bool>())
        << view.name;
    // There: the measured depth and the photo's colours.
    const Image map = *load_view_depth(scene, scene.views[static_cast<size_t>(with.input.context[v])]);
    const FarSide far = flying_pixels_to_far_side(image_to_tensor(map)[0][0], FlyingPixelOptions());
    const torch::Tensor measured = far.depth / with.input.normalization.scale;
    EXPECT_TRUE(torch::allclose(with.maps().depth[0][vi][0].index({changed}), measured.index({changed}), 1e-5, 1e-6));
    const torch::Tensor photo = far_side_colours(image_to_tensor(view.rgb)[0], far).clamp(0, 1);
    EXPECT_TRUE(torch::allclose(with.maps().rgb[0][vi].permute({1, 2, 0}).index({changed}),
                                photo.permute({1, 2, 0}).index({changed}), 1e-6, 1e-6));
  }
  EXPECT_GT(beside, 50);
  EXPECT_EQ(record["beside_object"], beside);
}

TEST(MeasuredSurface, NothingWithoutDepthMapsOrWithoutAlignment) {
  II_REQUIRE_DEFAULT_MODEL();
  const std::filesystem::path dir = test::synthetic_room("measured-surface-off", 4, 64, 22);
  const Scene scene = load_scene(dir);
  const Predictor predictor("", torch::kCPU, Precision::Float32);
  SceneInputOptions options = at_64_rows();
  options.geometry.align_depth = DepthPoints::none;  // the paper's depth: no measured surface either
  const Prediction raw = predictor.predict(scene, options);
  EXPECT_EQ(raw.describe_geometry()["measured_surface"], nlohmann::json::object());
  // A scene without depth maps, and the photos' own depth not asked for: nothing to put the
  // Gaussians on (with it: tests/geometry/stereo_depth_test.cpp).
  std::filesystem::remove_all(dir / "depth");
  options.geometry.align_depth = DepthPoints::depth_maps;
  options.geometry.measured_surface.from_photos = false;
  const nlohmann::json record = predictor.predict(scene, options).describe_geometry()["measured_surface"];
  EXPECT_EQ(record["views"].size(), 0u);
  EXPECT_EQ(record["gaussians"], 0);
}

}  // namespace
}  // namespace ii
