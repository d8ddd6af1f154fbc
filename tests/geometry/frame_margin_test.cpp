// Gaussians past the frame: each view's border pixels continued outward. Every new Gaussian
// takes its nearest border pixel's attributes and depth and sits on its own pixel's ray, checked
// against the rays of a larger camera (the same pose and focal length, the principal point moved
// by the margin) computed independently; a margin of 0 adds nothing; those another view sees
// through are dropped; the prediction joins them after the per-pixel rows and records them.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "camera/trajectory.h"
#include "model/default_model.h"
#include "geometry/frame_margin.h"
#include "model/model_input.h"
#include "predict/predictor.h"
#include "synthetic_room.h"
#include "test_support.h"

namespace ii {
namespace {
// A namespace of its own: the folder's test files are compiled together (CMake's unity build).
namespace frame_margin_test {

constexpr int kW = 12, kH = 8, kViews = 2;

Camera view_camera(int v) {
  Camera c;
  c.K = Intrinsics::from_fov(kW, kH, 60 * M_PI / 180, 2 * std::atan(std::tan(30 * M_PI / 180) * kH / kW));
  c.c2w = look_at({0.3 + v, 0.2, 3}, {0, 0, 0}, {0, 1, 0});
  return c;
}

struct Views {
  ModelInput input;
  GaussianMaps maps;
};

// Two views with seeded random attributes, their positions on their rays at their depth.
Views two_views() {
  Views s;
  torch::manual_seed(7);
  const std::vector<Camera> cameras = {view_camera(0), view_camera(1)};
  compute_ray_tensors(cameras, s.input.rays_o, s.input.rays_d, s.input.rays_d_un, s.input.plucker);
  s.input.view_cameras = cameras;
  s.maps.depth = 1.0 + torch::rand({1, kViews, 1, kH, kW});
  s.maps.rgb = torch::rand({1, kViews, 3, kH, kW});
  s.maps.opacity = torch::rand({1, kViews, 1, kH, kW});
  s.maps.scale = 0.01 * torch::rand({1, kViews, 3, kH, kW});
  s.maps.rotation = torch::randn({1, kViews, 4, kH, kW});
  s.maps.xyz = s.input.rays_o.permute({0, 3, 1, 2}).unsqueeze(0) +
               s.maps.depth * s.input.rays_d_un.permute({0, 3, 1, 2}).unsqueeze(0);
  return s;
}

TEST(FrameMargin, EachNewGaussianRepeatsItsNearestBorderPixelOnItsOwnRay) {
  const Views s = two_views();
  FrameMarginOptions options;
  options.fraction = 0.25;      // 2 pixels at 8 rows
  options.outer_fraction = 0;   // all of them dense
  ASSERT_EQ(frame_margin_pixels(kH, options), 2);
  ASSERT_EQ(frame_margin_outer_pixels(kH, options), 2);
  const GaussianSet g = gaussians_beyond_frame(s.maps, s.input, options);
  constexpr int m = 2, kOuterW = kW + 2 * m, kOuterH = kH + 2 * m;
  constexpr int per_view = kOuterW * kOuterH - kW * kH;
  ASSERT_EQ(g.size(), kViews * per_view);

  for (int v = 0; v < kViews; ++v) {
    // The same camera on a frame 2 pixels larger on every side: its pixel (u + m, v + m) is
    // this view's pixel (u, v), past the frame too.
    Camera larger = view_camera(v);
    larger.K.width = kOuterW;
    larger.K.height = kOuterH;
    larger.K.cx += m;
    larger.K.cy += m;
    const Rays rays = compute_rays(larger);
    int k = v * per_view;
    for (int row = -m; row < kH + m; ++row)
      for (int col = -m; col < kW + m; ++col) {
        if (row >= 0 && row < kH && col >= 0 && col < kW) continue;
        const int br = std::clamp(row, 0, kH - 1), bc = std::clamp(col, 0, kW - 1);
        const double depth = s.maps.depth[0][v][0][br][bc].item<double>();
        const size_t ray = static_cast<size_t>((row + m) * kOuterW + (col + m)) * 3;
        for (int c = 0; c < 3; ++c) {
          const double expected = rays.origin[ray + c] + depth * rays.dir_unnorm[ray + c];
          ASSERT_NEAR(g.means[k][c].item<double>(), expected, 1e-5) << "view " << v << " pixel " << col << "," << row;
          ASSERT_EQ(g.colors[k][c].item<float>(), s.maps.rgb[0][v][c][br][bc].item<float>());
          ASSERT_EQ(g.scales[k][c].item<float>(), s.maps.scale[0][v][c][br][bc].item<float>());
        }
        ASSERT_EQ(g.opacities[k].item<float>(), s.maps.opacity[0][v][0][br][bc].item<float>());
        for (int c = 0; c < 4; ++c) ASSERT_EQ(g.quats[k][c].item<float>(), s.maps.rotation[0][v][c][br][bc].item<float>());
        ++k;
      }
    ASSERT_EQ(k, (v + 1) * per_view);
  }
}

// Past the dense band, out to outer_fraction: one Gaussian per 2 x 2 block, at the block's
// centre on the larger camera's rays (the mean of its four pixels' rays), twice as wide and as
// opaque as its four pixels' Gaussians over each other, with the block corner's nearest border
// pixel's other attributes.
TEST(FrameMargin, PastTheDenseBandOneWiderGaussianPerBlock) {
  const Views s = two_views();
  FrameMarginOptions options;
  options.fraction = 0.25;       // 2 pixels dense at 8 rows
  options.outer_fraction = 0.5;  // out to 4 pixels
  options.outer_stride = 2;
  ASSERT_EQ(frame_margin_outer_pixels(kH, options), 4);
  const GaussianSet g = gaussians_beyond_frame(s.maps, s.input, options);
  constexpr int dense = 2, m = 4, kLargerW = kW + 2 * m + 1, kLargerH = kH + 2 * m + 1;

  int64_t k = 0;
  for (int v = 0; v < kViews; ++v) {
    Camera larger = view_camera(v);  // pixel (u + m, v + m) is this view's pixel (u, v)
    larger.K.width = kLargerW;
    larger.K.height = kLargerH;
    larger.K.cx += m;
    larger.K.cy += m;
    const Rays rays = compute_rays(larger);
    auto ray = [&](int row, int col, int c, const std::vector<float>& of) {
      return of[static_cast<size_t>((row + m) * kLargerW + (col + m)) * 3 + static_cast<size_t>(c)];
    };
    for (int row = -m; row < kH + m; ++row)
      for (int col = -m; col < kW + m; ++col) {
        const int past = std::max({-col, col - (kW - 1), -row, row - (kH - 1)});
        if (past <= 0) continue;
        const bool corner = (col + m) % 2 == 0 && (row + m) % 2 == 0;
        if (past > dense && !corner) continue;
        const int block = past > dense ? 2 : 1;
        const int br = std::clamp(row, 0, kH - 1), bc = std::clamp(col, 0, kW - 1);
        const double depth = s.maps.depth[0][v][0][br][bc].item<double>();
        ASSERT_LT(k, g.size());
        for (int c = 0; c < 3; ++c) {
          double origin = ray(row, col, c, rays.origin), direction = 0;
          for (int dr = 0; dr < block; ++dr)
            for (int dc = 0; dc < block; ++dc) direction += ray(row + dr, col + dc, c, rays.dir_unnorm);
          direction /= block * block;
          ASSERT_NEAR(g.means[k][c].item<double>(), origin + depth * direction, 1e-5)
              << "view " << v << " pixel " << col << "," << row;
          ASSERT_EQ(g.colors[k][c].item<float>(), s.maps.rgb[0][v][c][br][bc].item<float>());
          ASSERT_FLOAT_EQ(g.scales[k][c].item<float>(), block * s.maps.scale[0][v][c][br][bc].item<float>());
        }
        const double alpha = s.maps.opacity[0][v][0][br][bc].item<double>();
        ASSERT_NEAR(g.opacities[k].item<double>(), 1 - std::pow(1 - alpha, block * block), 1e-6);
        ++k;
      }
  }
  ASSERT_EQ(k, g.size());
}

TEST(FrameMargin, NoMarginAddsNothingAndABadFractionIsNamed) {
  const Views s = two_views();
  FrameMarginOptions none;
  none.fraction = 0;
  EXPECT_EQ(gaussians_beyond_frame(s.maps, s.input, none).size(), 0);
  FrameMarginOptions bad;
  bad.fraction = -0.1;
  EXPECT_EQ(test::error_message([&] { frame_margin_pixels(kH, bad); }),
            "frame margin: the fraction of the height must be between 0 and 1 (got -0.1)");
  FrameMarginOptions bad_stride;
  bad_stride.outer_stride = 0;
  EXPECT_EQ(test::error_message([&] { frame_margin_outer_pixels(kH, bad_stride); }),
            "frame margin: the outer stride must be between 1 and 16 pixels (got 0)");
  FrameMarginOptions none_outer;  // no dense band: nothing past it either
  none_outer.fraction = 0;
  none_outer.outer_fraction = 0.5;
  EXPECT_EQ(gaussians_beyond_frame(s.maps, s.input, none_outer).size(), 0);
}

// Where view 1 saw a far wall, view 0's margin in front of it is empty space: each of its margin
// Gaussians that lands inside view 1's picture is dropped, each outside kept (checked with the
// camera's own matrices); view 1's margin, behind view 0's near depth, stays whole; behind view 1's
// mask its depth is no evidence and nothing goes.
TEST(FrameMargin, WhatAnotherViewSeesThroughIsDropped) {
  Views s = two_views();
  s.maps.depth[0][1].fill_(10);
  s.maps.xyz[0][1] = s.input.rays_o[1].permute({2, 0, 1}) + 10 * s.input.rays_d_un[1].permute({2, 0, 1});
  FrameMarginOptions options;
  options.fraction = 0.25;
  const GaussianSet margin = gaussians_beyond_frame(s.maps, s.input, options);
  const int64_t per_view = margin.size() / kViews;
  std::vector<PreparedView> views(kViews);
  for (int v = 0; v < kViews; ++v) views[static_cast<size_t>(v)].name = "view " + std::to_string(v);
  const GaussianSet kept = without_seen_through(margin, s.maps, views, s.input.view_cameras);

  const Camera& other = s.input.view_cameras[1];
  const Eigen::Matrix4d w2c = other.w2c_opencv();
  std::vector<int64_t> expected;  // the rows kept
  int64_t inside = 0;
  for (int64_t k = 0; k < margin.size(); ++k) {
    const Eigen::Vector4d p(margin.means[k][0].item<double>(), margin.means[k][1].item<double>(),
                            margin.means[k][2].item<double>(), 1);
    const Eigen::Vector4d c = w2c * p;
    const double x = other.K.fx * c.x() / c.z() + other.K.cx, y = other.K.fy * c.y() / c.z() + other.K.cy;
    const bool lands_inside = c.z() > 0 && x >= 0 && y >= 0 && x < kW && y < kH;
    if (k < per_view && lands_inside) ++inside;
    else expected.push_back(k);
  }
  ASSERT_GT(inside, 10);  // the two cameras overlap: some of view 0's margin is in view 1's picture
  ASSERT_EQ(kept.size(), static_cast<int64_t>(expected.size()));
  EXPECT_TRUE(torch::equal(kept.means, margin.means.index({torch::tensor(expected)})));
  EXPECT_TRUE(torch::equal(kept.colors, margin.colors.index({torch::tensor(expected)})));

  // View 1's mask over its whole picture: its depth is the network's guess, nothing is dropped.
  views[1].mask = Image(kW, kH, 1, 1.f);
  EXPECT_EQ(without_seen_through(margin, s.maps, views, s.input.view_cameras).size(), margin.size());
}

TEST(FrameMargin, APredictionJoinsThemAfterThePixelsAndRecordsThem) {
  if (!has_default_model()) GTEST_SKIP() << "this build has no default model";
  const std::filesystem::path dir = test::synthetic_room("frame-margin", 4, 64, 8);
  const Scene scene = load_scene(dir);
  const Predictor predictor("", torch::kCPU, Precision::Float32);
  SceneInputOptions options;
  options.keep_object = true;
  options.preprocess.height = 64;
  const Prediction with = predictor.predict(scene, options);
  options.geometry.frame_margin.fraction = 0;
  options.geometry.behind_edges.fraction = 0;  // the per-pixel rows alone
  const Prediction without = predictor.predict(scene, options);
  // 8 pixels dense at 64 rows, then out to 16 one per 2 x 2 block (48 blocks along 96 pixels, 40
  // along the dense band's 80).
  const int64_t pixels = 4 * 64 * 64, continued = 4 * (80 * 80 - 64 * 64 + 48 * 48 - 40 * 40);
  EXPECT_EQ(without.gaussians().size(), pixels);
  const GaussianSet joined_set = with.gaussians();
  const int64_t margin = with.layer("frame_margin").size();
  ASSERT_EQ(joined_set.size(), pixels + margin + with.layer("behind_edges").size());  // then those behind depth edges
  EXPECT_TRUE(torch::equal(joined_set.means.narrow(0, 0, pixels), without.gaussians().means));
  EXPECT_TRUE(torch::equal(joined_set.means.narrow(0, pixels, margin), with.layer("frame_margin").means));
  const nlohmann::json recorded = with.describe_geometry()["frame_margin"];
  EXPECT_EQ(recorded["fraction"], 0.125);
  EXPECT_EQ(recorded["pixels"], 8);
  EXPECT_EQ(recorded["outer_pixels"], 16);
  EXPECT_EQ(recorded["outer_stride"], 2);
  EXPECT_EQ(recorded["gaussians"], margin);
  EXPECT_EQ(recorded["drop_seen_through"], true);
  EXPECT_GT(recorded["dropped"].get<int64_t>(), 0);  // the room's views overlap
  EXPECT_EQ(recorded["dropped"].get<int64_t>() + margin, continued);
  EXPECT_EQ(without.describe_geometry()["frame_margin"]["gaussians"], 0);
}

}  // namespace frame_margin_test
}  // namespace
}  // namespace ii
