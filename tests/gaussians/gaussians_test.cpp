// The Gaussian forms and their conversions: splat clouds, network maps, renderable sets.
#include <torch/nn/functional.h>
#include <gtest/gtest.h>

#include <cmath>

#include "gaussians/gaussians.h"
#include "test_support.h"

namespace ii {
namespace {

TEST(Gaussians, FromSplatCloud) {
  SplatCloud c;
  c.means = {1, 2, 3, 4, 5, 6};
  c.normals.assign(6, 0.f);
  c.sh_dc = {0.1f, 0.2f, 0.3f, 0.4f, 0.5f, 0.6f};
  c.sh_rest_per_channel = 3;  // degree 1, channel-major: R0 R1 R2 G0 G1 G2 B0 B1 B2
  for (int i = 0; i < 2; ++i)
    for (int k = 0; k < 9; ++k) c.sh_rest.push_back(static_cast<float>(100 * i + k));
  c.opacity_logit = {0.f, 2.f};
  c.log_scales = {0, 0, 0, -1, -2, -3};
  c.rotations = {1, 0, 0, 0, 0, 1, 0, 0};
  const GaussianSet g = gaussians_from_splats(c);
  EXPECT_EQ(g.sh_degree, 1);
  ASSERT_EQ(g.colors.sizes(), (std::vector<int64_t>{2, 4, 3}));
  EXPECT_FLOAT_EQ(g.colors[1][0][2].item<float>(), 0.6f);
  EXPECT_FLOAT_EQ(g.colors[1][2][0].item<float>(), 101.f);  // R, coefficient 2 (rest index 1)
  EXPECT_FLOAT_EQ(g.colors[1][1][1].item<float>(), 103.f);  // G, rest index 0
  EXPECT_FLOAT_EQ(g.colors[0][3][2].item<float>(), 8.f);    // B, rest index 2
  EXPECT_NEAR(g.opacities[0].item<float>(), 0.5f, 1e-6);
  EXPECT_NEAR(g.scales[1][2].item<float>(), std::exp(-3.f), 1e-6);
  EXPECT_EQ(gaussians_from_splats(c, 0).colors.size(1), 1);
  EXPECT_EQ(gaussians_from_splats(c, 0).sh_degree, 0);
}

TEST(Gaussians, FromNetworkMaps) {
  GaussianMaps m;
  m.xyz = torch::arange(2 * 3 * 4 * 5, torch::kFloat32).reshape({1, 2, 3, 4, 5});
  m.rgb = m.xyz * 0.01;
  m.rotation = torch::rand({1, 2, 4, 4, 5});
  m.scale = torch::rand({1, 2, 3, 4, 5});
  m.opacity = torch::rand({1, 2, 1, 4, 5});
  const GaussianSet g = gaussians_from_maps(m);
  ASSERT_EQ(g.means.sizes(), (std::vector<int64_t>{40, 3}));
  // Index v*H*W + i*W + j holds pixel (i, j) of view v.
  EXPECT_FLOAT_EQ(g.means[1 * 20 + 2 * 5 + 3][1].item<float>(), m.xyz[0][1][1][2][3].item<float>());
  EXPECT_EQ(g.opacities.dim(), 1);
  EXPECT_EQ(g.sh_degree, -1);
}

// A network prediction written as a PLY and read back renders what the maps do: the
// activations and their inverses agree (to float rounding).
TEST(Gaussians, SplatsOfAPredictionReadBackAsTheSameSet) {
  torch::manual_seed(2);
  GaussianMaps m;
  m.xyz = torch::randn({1, 2, 3, 4, 5});
  m.rgb = torch::rand({1, 2, 3, 4, 5});
  m.rotation = torch::nn::functional::normalize(torch::randn({1, 2, 4, 4, 5}),
                                                torch::nn::functional::NormalizeFuncOptions().dim(2));
  m.scale = torch::rand({1, 2, 3, 4, 5}) * 0.1 + 1e-3;
  m.opacity = torch::rand({1, 2, 1, 4, 5}) * 0.98 + 0.01;
  const GaussianSet g = gaussians_from_maps(m);
  const SplatCloud cloud = splats_from_gaussians(g);
  EXPECT_EQ(cloud.size(), 40u);
  EXPECT_EQ(cloud.normals, std::vector<float>(120, 0.f));
  const GaussianSet back = gaussians_from_splats(cloud);
  EXPECT_EQ(back.sh_degree, 0);
  EXPECT_TRUE(torch::equal(back.means, g.means.contiguous()));
  EXPECT_TRUE(torch::allclose(back.scales, g.scales, 1e-5, 1e-7));
  EXPECT_TRUE(torch::allclose(back.opacities, g.opacities, 1e-5, 1e-6));
  EXPECT_TRUE(torch::allclose(rgb_from_sh_dc(back.colors.select(1, 0)), g.colors, 1e-5, 1e-6));
}

// An SH set (as --refine-sh-degree fits) round-trips through the PLY's f_dc/f_rest layout.
TEST(Gaussians, ShSetsRoundTripThroughSplats) {
  torch::manual_seed(3);
  GaussianSet g;
  g.means = torch::randn({6, 3});
  g.quats = torch::randn({6, 4});
  g.scales = torch::rand({6, 3}) + 0.01;
  g.opacities = torch::rand({6}) * 0.9 + 0.05;
  g.colors = torch::randn({6, 16, 3});
  g.sh_degree = 2;  // the coefficients beyond degree 2 are not written
  const SplatCloud cloud = splats_from_gaussians(g);
  EXPECT_EQ(cloud.sh_rest_per_channel, 8);
  // Splat 1's second coefficient of G is f_rest_{8 + 1}.
  EXPECT_EQ(cloud.sh_rest[1 * 24 + 8 + 1], g.colors[1][2][1].item<float>());
  const GaussianSet back = gaussians_from_splats(cloud);
  EXPECT_EQ(back.sh_degree, 2);
  EXPECT_TRUE(torch::equal(back.colors, g.colors.narrow(1, 0, 9)));

  g.colors = torch::randn({6, 4, 3});
  EXPECT_EQ(test::error_message([&] { splats_from_gaussians(g); }),
            "splats_from_gaussians: SH degree 2 needs colours of shape (N, 9, 3) or more coefficients");
}

TEST(Gaussians, VisibleBoundsIgnoreFloatersAndTransparentSplats) {
  GaussianSet g;
  // 1000 splats evenly in the box [-1, 1] x [0, 2] x [4, 6], one far floater, one transparent giant offset.
  std::vector<float> means;
  for (int i = 0; i < 1000; ++i) {
    const float t = i / 999.f;
    means.insert(means.end(), {-1.f + 2 * t, 2 * t, 4.f + 2 * t});
  }
  means.insert(means.end(), {100.f, 100.f, 100.f});
  means.insert(means.end(), {-50.f, -50.f, -50.f});
  g.means = torch::tensor(means).reshape({-1, 3});
  g.opacities = torch::full({1002}, 0.9f);
  g.opacities[1001] = 0.01f;
  const BoundingSphere b = visible_bounds(g);
  EXPECT_NEAR(b.centre.x(), 0.0, 0.05);
  EXPECT_NEAR(b.centre.y(), 1.0, 0.05);
  EXPECT_NEAR(b.centre.z(), 5.0, 0.05);
  EXPECT_NEAR(b.radius, 0.5 * std::sqrt(3.0) * 2 * 0.96, 0.05);
  EXPECT_EQ(test::error_message([] { visible_bounds(GaussianSet()); }), "visible_bounds: no splats");
}

}  // namespace
}  // namespace ii
