// The reference's region covered: one flat splat per region pixel, on the reference's depth along
// its own ray, in the reference's colour and the option's opacity; nothing without a region or
// with opacity 0; a prediction joins them after the pixels and those past the frames, records
// them, and leaves a reconstruction (no mask) alone.
#include <gtest/gtest.h>

#include <cmath>

#include "camera/trajectory.h"
#include "data/scene.h"
#include "model/default_model.h"
#include "predict/predictor.h"
#include "geometry/region_cover.h"
#include "synthetic_room.h"
#include "test_support.h"

namespace ii {
namespace {
// A namespace of its own: the folder's test files are compiled together (CMake's unity build).
namespace region_cover_test {

constexpr int kW = 16, kH = 12;

PreparedView reference_with_square(int top, int left, int size) {
  PreparedView v;
  v.name = "reference";
  v.rgb = Image(kW, kH, 3);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x)
      for (int c = 0; c < 3; ++c) v.rgb.at(y, x, c) = static_cast<float>((x + 2 * y + 5 * c) % 11) / 10.f;
  v.mask = Image(kW, kH, 1);
  for (int y = top; y < top + size; ++y)
    for (int x = left; x < left + size; ++x) v.mask->at(y, x) = 1.f;
  v.camera.K = Intrinsics::from_fov(kW, kH, 60 * M_PI / 180, 2 * std::atan(std::tan(30 * M_PI / 180) * kH / kW));
  v.camera.c2w = look_at({0.4, 0.3, 3}, {0, 0, 0}, {0, 1, 0});
  return v;
}

TEST(RegionCover, OneSplatPerRegionPixelOnItsDepthInTheReferencesColour) {
  const PreparedView ref = reference_with_square(3, 5, 4);
  const torch::Tensor depth = torch::linspace(1.5, 2.5, kW).repeat({kH, 1});  // a slanted wall
  RegionCoverOptions options;
  const GaussianSet cover =
      region_cover_gaussians(ref, ref.camera, depth, options, torch::zeros({1}, torch::kFloat64));
  ASSERT_EQ(cover.size(), 16);
  EXPECT_EQ(cover.means.scalar_type(), torch::kFloat64);  // the dtype of `like`
  EXPECT_TRUE(torch::allclose(cover.opacities.to(torch::kFloat32), torch::full({16}, 0.3f)));
  const Eigen::Matrix4d w2c = ref.camera.w2c_opencv();
  int64_t row = 0;
  for (int y = 3; y < 7; ++y)
    for (int x = 5; x < 9; ++x, ++row) {
      const Eigen::Vector3d p(cover.means[row][0].item<double>(), cover.means[row][1].item<double>(),
                              cover.means[row][2].item<double>());
      const Eigen::Vector3d c = w2c.block<3, 3>(0, 0) * p + w2c.block<3, 1>(0, 3);
      // On the pixel's own ray (its centre) at the depth given.
      EXPECT_NEAR(c.z(), depth[y][x].item<double>(), 1e-5);
      EXPECT_NEAR(ref.camera.K.fx * c.x() / c.z() + ref.camera.K.cx, x + 0.5, 1e-4);
      EXPECT_NEAR(ref.camera.K.fy * c.y() / c.z() + ref.camera.K.cy, y + 0.5, 1e-4);
      for (int k = 0; k < 3; ++k) EXPECT_NEAR(cover.colors[row][k].item<double>(), ref.rgb.at(y, x, k), 1e-6);
    }
}

TEST(RegionCover, NothingWithoutARegionOrWithOpacityZero) {
  const torch::Tensor depth = torch::full({kH, kW}, 2.f), like = torch::zeros({1});
  PreparedView ref = reference_with_square(3, 5, 4);
  RegionCoverOptions off;
  off.opacity = 0;
  EXPECT_EQ(region_cover_gaussians(ref, ref.camera, depth, off, like).size(), 0);
  PreparedView empty = reference_with_square(0, 0, 0);
  EXPECT_EQ(region_cover_gaussians(empty, empty.camera, depth, {}, like).size(), 0);
  ref.mask.reset();
  EXPECT_EQ(region_cover_gaussians(ref, ref.camera, depth, {}, like).size(), 0);
  const PreparedView square = reference_with_square(3, 5, 4);
  EXPECT_EQ(test::error_message([&] {
              region_cover_gaussians(square, square.camera, torch::full({kH, kW + 1}, 2.f), {}, like);
            }),
            "region cover: the reference's depth is not its mask's size (16x12)");
}

TEST(RegionCover, APredictionJoinsItAfterThePixelsAndRecordsIt) {
  if (!has_default_model()) GTEST_SKIP() << "this build has no default model";
  const std::filesystem::path dir = test::synthetic_room("region-cover", 4, 64, 8);
  const Scene scene = load_scene(dir);
  const Predictor predictor("", torch::kCPU, Precision::Float32);
  SceneInputOptions options;
  options.preprocess.height = 64;
  options.geometry.frame_margin.fraction = 0;
  options.geometry.behind_edges.fraction = 0;  // the pixels' rows, then the cover's
  const Prediction with = predictor.predict(scene, options);
  options.geometry.region_cover.opacity = 0;
  const Prediction without = predictor.predict(scene, options);
  const int64_t pixels = 4 * 64 * 64;
  ASSERT_TRUE(with.input.views.front().mask.has_value());
  int64_t region = 0;
  for (float m : with.input.views.front().mask->pixels) region += m > 0.5f;
  ASSERT_GT(region, 0);
  EXPECT_EQ(without.gaussians().size(), pixels);
  const GaussianSet all = with.gaussians();
  ASSERT_EQ(all.size(), pixels + region);
  EXPECT_TRUE(torch::equal(all.means.narrow(0, 0, pixels), without.gaussians().means));
  EXPECT_TRUE(torch::equal(all.means.narrow(0, pixels, region), with.layer("region_cover").means));
  const nlohmann::json recorded = with.describe_geometry()["region_cover"];
  EXPECT_EQ(recorded["opacity"], 0.3);
  EXPECT_EQ(recorded["gaussians"], region);
  EXPECT_EQ(without.describe_geometry()["region_cover"]["gaussians"], 0);
  // A reconstruction of the scene as captured has no region to cover.
  options.geometry.region_cover.opacity = 0.3;
  options.keep_object = true;
  EXPECT_EQ(predictor.predict(scene, options).layer("region_cover").size(), 0);
}

}  // namespace region_cover_test
}  // namespace
}  // namespace ii
