// The reference's region on the surface around it: each region pixel takes the depth of the
// surrounding surface whose colour it shares (a red half and a blue half at two depths); with a
// depth map's slopes a slanted floor goes on exactly, held flat it does not; without a ring there
// is no depth; bad values are named; in a prediction the region's pixels become opaque splats in
// the reference's colours and nothing else changes, and those whose weighted depth fell between two
// surfaces go to the far one; the fused kernel of the ring's weights gives LibTorch's softmax.
#include <gtest/gtest.h>

#include <cmath>

#include "common/cpu_features.h"
#include "model/default_model.h"
#include "predict/predictor.h"
#include "geometry/region_surface.h"
#include "synthetic_room.h"
#include "test_support.h"

namespace ii {
namespace {
// A namespace of its own: the folder's test files are compiled together (CMake's unity build).
namespace region_surface_test {

using torch::indexing::None;
using torch::indexing::Slice;

constexpr int kW = 40, kH = 30;

// A square region of side 10 in the middle of the picture.
torch::Tensor square_region() {
  torch::Tensor region = torch::zeros({kH, kW}, torch::kBool);
  region.index_put_({Slice(10, 20), Slice(15, 25)}, true);
  return region;
}

// The fused kernel (geometry/region_weights.h) against LibTorch's softmax and product: ring sizes
// that are and are not whole vectors, features as wide as a 512-row picture's (logits in the
// thousands: the row's largest must be taken out before the exponentials).
TEST(RegionSurface, TheFusedRingWeightsAreLibTorchsSoftmax) {
  if (!cpu_features().has(CpuIsa::Avx2)) GTEST_SKIP() << "this CPU has no AVX2: the fused kernel is not used";
  torch::manual_seed(7);
  for (const int64_t m : {1, 8, 13, 2757}) {
    for (const double spread : {1.0, 30.0}) {
      const torch::Tensor pixels = torch::rand({301, 5}) * spread;
      const torch::Tensor ring = torch::rand({m, 5}) * spread;
      const torch::Tensor planes = torch::randn({m, 3});
      const torch::Tensor fused = ring_weighted_planes(pixels, ring, planes, true);
      const torch::Tensor libtorch = ring_weighted_planes(pixels, ring, planes, false);
      // The truth in double precision: both float forms round the logits (2 a.b - |b|^2 cancels).
      const torch::Tensor p64 = pixels.to(torch::kFloat64), r64 = ring.to(torch::kFloat64);
      const torch::Tensor exact = torch::softmax(2 * p64.matmul(r64.t()) - r64.pow(2).sum(1).view({1, -1}), 1)
                                      .matmul(planes.to(torch::kFloat64));
      const double fused_error = (fused.to(torch::kFloat64) - exact).abs().max().item<double>();
      const double libtorch_error = (libtorch.to(torch::kFloat64) - exact).abs().max().item<double>();
      EXPECT_TRUE(fused.isfinite().all().item<bool>()) << m << " " << spread;
      EXPECT_LT(fused_error, std::max(2 * libtorch_error, 1e-5)) << m << " " << spread << " " << libtorch_error;
    }
  }
  EXPECT_EQ(test::error_message(
                [] { ring_weighted_planes(torch::zeros({4, 5}), torch::zeros({0, 5}), torch::zeros({0, 3})); }),
            "region surface: the ring's weights need (n, 5) pixels, (m, 5) ring features and (m, 3) planes, m > 0");
}

TEST(RegionSurface, EachPixelTakesTheDepthOfTheSurfaceItsColourMatches) {
  // Left half red at depth 2, right half blue at depth 5; the region straddles them and shows both.
  torch::Tensor measured = torch::full({kH, kW}, 2.f), colour = torch::zeros({3, kH, kW});
  measured.index_put_({Slice(), Slice(kW / 2, None)}, 5.f);
  colour.index_put_({0, Slice(), Slice(None, kW / 2)}, 1.f);
  colour.index_put_({2, Slice(), Slice(kW / 2, None)}, 1.f);
  const torch::Tensor region = square_region();
  measured.index_put_({region}, 0.f);  // unknown where the object stood
  int64_t ring = 0;
  const torch::Tensor depth = depth_from_surroundings(measured, region, colour, false, {}, &ring);
  EXPECT_GT(ring, 0);
  for (int row = 0; row < kH; ++row)
    for (int col = 0; col < kW; ++col) {
      const float d = depth[row][col].item<float>();
      if (!region[row][col].item<bool>()) {
        EXPECT_EQ(d, 0.f) << col << "," << row;
        continue;
      }
      if (std::abs(col + 0.5 - kW / 2.0) < 3) continue;  // the colours blur across the seam here
      EXPECT_NEAR(d, col < kW / 2 ? 2.f : 5.f, 0.02) << col << "," << row;
    }
}

TEST(RegionSurface, ADepthMapsSlopeGoesOnAndHeldFlatItDoesNot) {
  // A floor seen obliquely: inverse depth falls linearly towards the top of the picture.
  const torch::Tensor rows = torch::arange(kH, torch::kFloat32).view({kH, 1}).expand({kH, kW});
  const torch::Tensor truth = (0.2f + 0.02f * rows).reciprocal();
  const torch::Tensor region = square_region();
  const torch::Tensor measured = torch::where(region, torch::zeros_like(truth), truth);
  const torch::Tensor colour = torch::full({3, kH, kW}, 0.5f);
  auto error = [&](bool slopes) {
    const torch::Tensor depth = depth_from_surroundings(measured, region, colour, slopes, {});
    return ((depth.index({region}) / truth.index({region})).log().abs()).max().item<double>();
  };
  EXPECT_LT(error(true), 1e-3);
  EXPECT_GT(error(false), 0.05);  // the ring's depths averaged: the floor's rows flattened
}

TEST(RegionSurface, NoRingNoDepthAndBadValuesAreNamed) {
  const torch::Tensor region = square_region(), colour = torch::zeros({3, kH, kW});
  EXPECT_EQ(depth_from_surroundings(torch::zeros({kH, kW}), region, colour, true, {}).count_nonzero().item<int64_t>(),
            0);
  EXPECT_EQ(depth_from_surroundings(torch::ones({kH, kW}), torch::zeros({kH, kW}, torch::kBool), colour, true, {})
                .count_nonzero()
                .item<int64_t>(),
            0);
  RegionSurfaceOptions bad;
  bad.opacity = 2;
  EXPECT_EQ(test::error_message([&] { check_region_surface_options(bad); }),
            "region surface: the opacity must be between 0 and 1 (got 2)");
  bad = {};
  bad.colour = 0;
  EXPECT_EQ(test::error_message([&] { check_region_surface_options(bad); }),
            "region surface: the colour width must be above 0 (got 0)");
  EXPECT_EQ(test::error_message([&] {
              depth_from_surroundings(torch::ones({kH, kW}), region, torch::zeros({3, kH, kW + 1}), false, {});
            }),
            "region surface: the depth, region and colour must be one picture's size (40x30)");
}

// In a prediction of a room with depth maps: the reference's region (its mask grown by the
// measured surface's margin) becomes opaque splats in the reference's colours along the slopes
// of its depth map; every other Gaussian is as without it.
TEST(RegionSurface, APredictionPutsTheReferencesRegionOnTheSurfaceAroundIt) {
  if (!has_default_model()) GTEST_SKIP() << "this build has no default model";
  const std::filesystem::path dir = test::synthetic_room("region-surface", 4, 64, 8);
  const Scene scene = load_scene(dir);
  const Predictor predictor("", torch::kCPU, Precision::Float32);
  SceneInputOptions options;
  options.preprocess.height = 64;
  options.geometry.floaters.fade = 1;  // the opacities as this step leaves them (fading weighs every view's)
  const Prediction with = predictor.predict(scene, options);
  options.geometry.region_surface.opacity = 0;
  const Prediction without = predictor.predict(scene, options);
  const PreparedView& reference = with.input.views.front();
  ASSERT_TRUE(reference.mask.has_value());
  const torch::Tensor region = grown_mask(reference, options.geometry.measured_surface.mask_margin);
  const int64_t pixels = region.sum().item<int64_t>();
  ASSERT_GT(pixels, 0);
  const nlohmann::json recorded = with.describe_geometry()["region_surface"];
  EXPECT_EQ(recorded["opacity"], 0.95);
  EXPECT_EQ(recorded["slopes"], true);  // the room's depth maps
  EXPECT_GT(recorded["ring"].get<int64_t>(), 0);
  EXPECT_EQ(recorded["gaussians"], pixels);
  EXPECT_EQ(without.describe_geometry()["region_surface"]["gaussians"], 0);

  const torch::Tensor outside = region.logical_not().flatten();
  auto reference_map = [](const torch::Tensor& map) {  // the reference's (C, H x W)
    return map[0][0].reshape({map.size(2), -1}).to(torch::kFloat32);
  };
  for (auto member : {&GaussianMaps::xyz, &GaussianMaps::opacity, &GaussianMaps::rgb, &GaussianMaps::scale}) {
    const torch::Tensor a = reference_map(with.maps().*member), b = reference_map(without.maps().*member);
    EXPECT_TRUE(torch::equal(a.index({Slice(), outside}), b.index({Slice(), outside})));
    EXPECT_FALSE(torch::equal(a.index({Slice(), region.flatten()}), b.index({Slice(), region.flatten()})));
  }
  for (int64_t v = 1; v < 4; ++v) EXPECT_TRUE(torch::equal(with.maps().xyz[0][v], without.maps().xyz[0][v]));
  const torch::Tensor inside = region.flatten();
  EXPECT_GE(reference_map(with.maps().opacity).index({Slice(), inside}).min().item<float>(), 0.95f);
  const torch::Tensor photo =
      torch::from_blob(const_cast<float*>(reference.rgb.pixels.data()), {64 * 64, reference.rgb.channels})
          .index({Slice(), Slice(0, 3)})
          .t();
  EXPECT_TRUE(torch::allclose(reference_map(with.maps().rgb).index({Slice(), inside}),
                              photo.index({Slice(), inside}).clamp(0, 1)));
  // Region pixels whose weighted depth fell between two surfaces went to the far one: only they
  // differ from a run that keeps them, each farther than it was.
  options.geometry.region_surface.opacity = 0.95;
  options.geometry.region_surface.far_side = false;
  const Prediction kept = predictor.predict(scene, options);
  const int64_t moved = recorded["far_side"].get<int64_t>();
  EXPECT_GT(moved, 0);
  EXPECT_EQ(kept.describe_geometry()["region_surface"]["far_side"], 0);
  const torch::Tensor depth_moved = reference_map(with.maps().depth)[0], depth_kept = reference_map(kept.maps().depth)[0];
  const torch::Tensor differ = depth_moved.ne(depth_kept);
  EXPECT_EQ(differ.sum().item<int64_t>(), moved);
  EXPECT_FALSE(differ.logical_and(inside.logical_not()).any().item<bool>());
  EXPECT_TRUE(depth_moved.index({differ}).gt(depth_kept.index({differ})).all().item<bool>());
  options.geometry.region_surface.far_side = true;
  // A reconstruction of the scene as captured has no region.
  options.keep_object = true;
  EXPECT_EQ(predictor.predict(scene, options).describe_geometry()["region_surface"]["gaussians"], 0);
}

}  // namespace region_surface_test
}  // namespace
}  // namespace ii
