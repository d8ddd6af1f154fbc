// Gaussians behind depth edges: a near square in front of a far wall. Each square pixel within
// reach of the wall's pixels two from the edge gets one Gaussian on its own ray at the wall's
// depth with one of those wall pixels' attributes; the square's middle, beyond reach, gets none;
// a mask keeps its pixels out as sources and as targets; 0 adds nothing; a bad value is named.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "camera/trajectory.h"
#include "geometry/behind_edges.h"
#include "model/default_model.h"
#include "model/model_input.h"
#include "predict/predictor.h"
#include "synthetic_room.h"
#include "test_support.h"

namespace ii {
namespace {
// A namespace of its own: the folder's test files are compiled together (CMake's unity build).
namespace behind_edges_test {

constexpr int kW = 24, kH = 16;
constexpr int kLeft = 8, kRight = 15, kTop = 4, kBottom = 11;  // the near square, inclusive
constexpr double kNear = 1, kFar = 4;

bool in_square(int row, int col) { return row >= kTop && row <= kBottom && col >= kLeft && col <= kRight; }

// Chebyshev distance from a pixel outside the square to it.
int to_square(int row, int col) {
  const int dr = std::max({kTop - row, row - kBottom, 0}), dc = std::max({kLeft - col, col - kRight, 0});
  return std::max(dr, dc);
}

struct Wall {
  ModelInput input;
  GaussianMaps maps;
  std::vector<PreparedView> views;
};

Wall near_square_on_a_wall() {
  Wall s;
  torch::manual_seed(11);
  Camera c;
  c.K = Intrinsics::from_fov(kW, kH, 60 * M_PI / 180, 2 * std::atan(std::tan(30 * M_PI / 180) * kH / kW));
  c.c2w = look_at({0.3, 0.2, 3}, {0, 0, 0}, {0, 1, 0});
  compute_ray_tensors({c}, s.input.rays_o, s.input.rays_d, s.input.rays_d_un, s.input.plucker);
  s.input.view_cameras = {c};
  s.maps.depth = torch::full({1, 1, 1, kH, kW}, kFar);
  s.maps.depth.index_put_({0, 0, 0, torch::indexing::Slice(kTop, kBottom + 1), torch::indexing::Slice(kLeft, kRight + 1)},
                          kNear);
  s.maps.rgb = torch::rand({1, 1, 3, kH, kW});
  s.maps.opacity = torch::rand({1, 1, 1, kH, kW});
  s.maps.scale = 0.01 * torch::rand({1, 1, 3, kH, kW});
  s.maps.rotation = torch::randn({1, 1, 4, kH, kW});
  s.maps.xyz = s.input.rays_o.permute({0, 3, 1, 2}).unsqueeze(0) +
               s.maps.depth * s.input.rays_d_un.permute({0, 3, 1, 2}).unsqueeze(0);
  s.views.resize(1);
  s.views[0].name = "view";
  return s;
}

TEST(BehindEdges, TheWallGoesOnUnderTheSquaresEdgeOnItsRays) {
  const Wall s = near_square_on_a_wall();
  BehindEdgesOptions options;
  options.fraction = 3.0 / kH;  // 3 pixels
  ASSERT_EQ(behind_edges_pixels(kH, options), 3);
  const GaussianSet g = gaussians_behind_edges(s.maps, s.input, s.views, options);

  // The sources: wall pixels two from the square. The targets: square pixels within 3 of one,
  // i.e. the square's two outer rings (its middle 4 x 4 is 4 or more away).
  int64_t k = 0;
  for (int row = 0; row < kH; ++row)
    for (int col = 0; col < kW; ++col) {
      if (!in_square(row, col)) continue;
      const bool outer = row <= kTop + 1 || row >= kBottom - 1 || col <= kLeft + 1 || col >= kRight - 1;
      if (!outer) continue;
      ASSERT_LT(k, g.size());
      const size_t ray = static_cast<size_t>(row * kW + col);
      for (int c = 0; c < 3; ++c) {
        const double expected = s.input.rays_o[0][row][col][c].item<double>() +
                                kFar * s.input.rays_d_un[0][row][col][c].item<double>();
        ASSERT_NEAR(g.means[k][c].item<double>(), expected, 1e-5) << "pixel " << col << "," << row << " ray " << ray;
      }
      // Its attributes are one source's, within reach.
      bool found = false;
      for (int r2 = row - 3; r2 <= row + 3 && !found; ++r2)
        for (int c2 = col - 3; c2 <= col + 3 && !found; ++c2) {
          if (r2 < 0 || c2 < 0 || r2 >= kH || c2 >= kW || in_square(r2, c2) || to_square(r2, c2) != 2) continue;
          found = g.colors[k][0].item<float>() == s.maps.rgb[0][0][0][r2][c2].item<float>() &&
                  g.opacities[k].item<float>() == s.maps.opacity[0][0][0][r2][c2].item<float>() &&
                  g.scales[k][1].item<float>() == s.maps.scale[0][0][1][r2][c2].item<float>() &&
                  g.quats[k][3].item<float>() == s.maps.rotation[0][0][3][r2][c2].item<float>();
        }
      ASSERT_TRUE(found) << "pixel " << col << "," << row;
      ++k;
    }
  EXPECT_EQ(k, 8 * 8 - 4 * 4);
  EXPECT_EQ(g.size(), k);
}

TEST(BehindEdges, AMaskedPixelIsNeitherSourceNorTarget) {
  Wall s = near_square_on_a_wall();
  BehindEdgesOptions options;
  options.fraction = 3.0 / kH;
  const int64_t all = gaussians_behind_edges(s.maps, s.input, s.views, options).size();
  // The left half of the picture masked: the square's left columns get nothing, and its right
  // columns only what the unmasked wall two from the edge gives within reach.
  s.views[0].mask = Image(kW, kH, 1, 0.f);
  for (int row = 0; row < kH; ++row)
    for (int col = 0; col < kW / 2; ++col) s.views[0].mask->at(row, col, 0) = 1.f;
  const GaussianSet g = gaussians_behind_edges(s.maps, s.input, s.views, options);
  EXPECT_GT(g.size(), 0);
  EXPECT_LT(g.size(), all);
  const torch::Tensor w2c = torch::from_blob(const_cast<double*>(s.input.view_cameras[0].w2c_opencv().data()), {4, 4},
                                             torch::kFloat64)
                                .t()
                                .to(torch::kFloat32);
  for (int64_t k = 0; k < g.size(); ++k) {
    const torch::Tensor p = torch::cat({g.means[k].to(torch::kFloat32), torch::ones({1})});
    const torch::Tensor c = w2c.matmul(p);
    const double x = s.input.view_cameras[0].K.fx * c[0].item<double>() / c[2].item<double>() +
                     s.input.view_cameras[0].K.cx;
    EXPECT_GE(x, kW / 2 - 0.01) << "a Gaussian behind a masked pixel";
  }
}

TEST(BehindEdges, NoneAddsNothingAndABadValueIsNamed) {
  const Wall s = near_square_on_a_wall();
  BehindEdgesOptions none;
  none.fraction = 0;
  EXPECT_EQ(gaussians_behind_edges(s.maps, s.input, s.views, none).size(), 0);
  BehindEdgesOptions flat;  // no edge as steep as this: nothing
  flat.jump = 5;
  EXPECT_EQ(gaussians_behind_edges(s.maps, s.input, s.views, flat).size(), 0);
  BehindEdgesOptions bad;
  bad.fraction = 2;
  EXPECT_EQ(test::error_message([&] { behind_edges_pixels(kH, bad); }),
            "behind edges: the fraction of the height must be between 0 and 1 (got 2)");
  bad.fraction = 0.1;
  bad.jump = 0;
  EXPECT_EQ(test::error_message([&] { behind_edges_pixels(kH, bad); }),
            "behind edges: the depth jump must be above 0 and at most 10 (got 0)");
  bad.depth_map_factor = 0.5;
  EXPECT_EQ(test::error_message([&] { behind_edges_for(bad, true); }),
            "behind edges: the depth maps' factor must be between 1 and 16 (got 0.5)");
}

// In a prediction they follow the frame margin's Gaussians, less those another view sees through,
// and the record says how many of each.
TEST(BehindEdges, APredictionJoinsThemAfterTheMarginAndRecordsThem) {
  if (!has_default_model()) GTEST_SKIP() << "this build has no default model";
  const std::filesystem::path dir = test::synthetic_room("behind-edges", 4, 64, 8);
  const Scene scene = load_scene(dir);
  const Predictor predictor("", torch::kCPU, Precision::Float32);
  SceneInputOptions options;
  options.keep_object = true;
  options.preprocess.height = 64;
  const Prediction with = predictor.predict(scene, options);
  // The room's depth maps measured its edges: twice as far under the near side.
  ASSERT_EQ(with.describe_geometry()["measured_surface"]["source"], "depth maps");
  const BehindEdgesOptions used = behind_edges_for(options.geometry.behind_edges, true);
  EXPECT_EQ(used.fraction, 0.0625);
  EXPECT_EQ(behind_edges_for(options.geometry.behind_edges, false).fraction, 0.03125);
  const int64_t found = gaussians_behind_edges(with.maps(), with.input.input, with.input.views, used).size();
  const int64_t kept = with.layer("behind_edges").size();
  EXPECT_GT(kept, 0);  // the room's table stands in front of its floor
  const nlohmann::json recorded = with.describe_geometry()["behind_edges"];
  EXPECT_EQ(recorded["fraction"], 0.0625);
  EXPECT_EQ(recorded["pixels"], 4);
  EXPECT_EQ(recorded["jump"], 0.1);
  EXPECT_EQ(recorded["gaussians"], kept);
  EXPECT_EQ(recorded["dropped"].get<int64_t>() + kept, found);

  options.geometry.behind_edges.fraction = 0;
  const Prediction without = predictor.predict(scene, options);
  EXPECT_EQ(without.layer("behind_edges").size(), 0);
  const GaussianSet joined_with = with.gaussians(), joined_without = without.gaussians();
  ASSERT_EQ(joined_with.size(), joined_without.size() + kept);
  const int64_t before = 4 * 64 * 64 + with.layer("frame_margin").size();
  EXPECT_TRUE(torch::equal(joined_with.means.narrow(0, 0, before), joined_without.means.narrow(0, 0, before)));
  EXPECT_TRUE(torch::equal(joined_with.means.narrow(0, before, kept), with.layer("behind_edges").means));
}

}  // namespace behind_edges_test
}  // namespace
}  // namespace ii
