// The tiled CPU renderer against the direct reference renderer, thread-count determinism and
// degenerate input.
#include <gtest/gtest.h>

#include <limits>

#include <Eigen/Geometry>

#include "render/rasterizer.h"
#include "render/render_test_util.h"
#include "test_support.h"

namespace ii {
namespace {

RenderCamera scene_camera(int w = 40, int h = 32) {
  return test::opencv_camera(w, h, 0.8 * w, Eigen::Vector3d(0.1, -0.05, -4.0));
}

void expect_close(const RenderOutput& a, const RenderOutput& b, double tol) {
  EXPECT_LT(test::max_abs_diff(a.rgb, b.rgb), tol);
  EXPECT_LT(test::max_abs_diff(a.alpha, b.alpha), tol);
  // Depth is in scene units (about 4 here) and divides by alpha.
  EXPECT_LT(test::max_abs_diff(a.depth * a.alpha, b.depth * b.alpha), 10 * tol);
}

TEST(Rasterizer, MatchesReferenceRgbAndSh) {
  for (int degree = -1; degree <= 3; ++degree) {
    SCOPED_TRACE("sh_degree " + std::to_string(degree));
    const GaussianSet g = test::random_scene(60, degree, torch::kFloat32, 10 + degree);
    const RenderCamera cam = scene_camera();
    RenderOptions opt;
    opt.background = {0.2f, 0.5f, 0.9f};
    const RenderOutput fast = render(g, cam, opt), ref = render_reference(g, cam, opt);
    ASSERT_EQ(fast.rgb.sizes(), (std::vector<int64_t>{32, 40, 3}));
    ASSERT_EQ(fast.alpha.sizes(), (std::vector<int64_t>{32, 40, 1}));
    ASSERT_EQ(fast.depth.sizes(), (std::vector<int64_t>{32, 40, 1}));
    expect_close(fast, ref, 2e-5);
    EXPECT_GT(fast.alpha.max().item<float>(), 0.9f);  // the scene is actually seen
  }
}

// Many small Gaussians over several tiles, some reaching the 1e-4 transmittance stop and the
// 0.999 alpha clamp; also a higher SH degree stored than used.
TEST(Rasterizer, MatchesReferenceDenseScene) {
  GaussianSet g = test::random_scene(400, 3, torch::kFloat64, 3, 1.2, 0.08);
  g.opacities = g.opacities.clamp_max(0.9) + 0.0995;  // up to 0.9995 > 0.999
  g.sh_degree = 2;
  const RenderCamera cam = scene_camera(70, 45);
  const RenderOutput fast = render(g, cam), ref = render_reference(g, cam);
  expect_close(fast, ref, 1e-10);
  EXPECT_GT(fast.alpha.max().item<double>(), 1 - 1e-4 - 1e-3);
}

TEST(Rasterizer, OffCentrePrincipalPointAndWideFov) {
  const GaussianSet g = test::random_scene(80, 1, torch::kFloat64, 5, 2.5, 0.2);
  RenderCamera cam = scene_camera(33, 17);
  cam.camera.K.cx = 5.3;
  cam.camera.K.cy = 14.1;
  cam.camera.K.fx = 9.0;  // very wide: many x/z clamped in the Jacobian
  cam.camera.K.fy = 11.0;
  expect_close(render(g, cam), render_reference(g, cam), 1e-10);
}

TEST(Rasterizer, RotatedCameraFromCameraH) {
  // An OpenGL camera looking at the origin from an oblique position.
  const GaussianSet g = test::random_scene(50, 3, torch::kFloat64, 6);
  RenderCamera cam;
  cam.camera.K = Intrinsics::from_fov(48, 36, 1.0, 0.8);
  const Eigen::Vector3d eye(2.5, 1.5, 2.0), up(0, 1, 0);
  const Eigen::Vector3d back = eye.normalized(), right = up.cross(back).normalized(), up2 = back.cross(right);
  cam.camera.c2w.setIdentity();
  cam.camera.c2w.block<3, 1>(0, 0) = right;
  cam.camera.c2w.block<3, 1>(0, 1) = up2;
  cam.camera.c2w.block<3, 1>(0, 2) = back;
  cam.camera.c2w.block<3, 1>(0, 3) = eye;
  const RenderOutput fast = render(g, cam), ref = render_reference(g, cam);
  expect_close(fast, ref, 1e-10);
  EXPECT_GT(fast.alpha.max().item<double>(), 0.5);
}

TEST(Rasterizer, SameForAnyThreadCount) {
  GaussianSet g = test::random_scene(3000, 3, torch::kFloat32, 7, 1.5, 0.05);
  const RenderCamera cam = scene_camera(100, 70);
  for (torch::Tensor* t : {&g.means, &g.quats, &g.scales, &g.opacities, &g.colors}) t->set_requires_grad(true);
  const int threads = at::get_num_threads();
  std::vector<std::vector<torch::Tensor>> results;
  for (int n : {1, 2, 3}) {
    at::set_num_threads(n);
    for (torch::Tensor* t : {&g.means, &g.quats, &g.scales, &g.opacities, &g.colors}) t->mutable_grad() = torch::Tensor();
    const RenderOutput out = render(g, cam);
    const auto w = torch::linspace(-1, 1, out.rgb.numel()).reshape(out.rgb.sizes());
    ((out.rgb * w).sum() + out.alpha.sum() + 0.1 * out.depth.sum()).backward();
    results.push_back({out.rgb, out.alpha, out.depth, g.means.grad(), g.quats.grad(), g.scales.grad(),
                       g.opacities.grad(), g.colors.grad()});
  }
  at::set_num_threads(threads);
  for (size_t r = 1; r < results.size(); ++r)
    for (size_t i = 0; i < results[0].size(); ++i)
      EXPECT_TRUE(torch::equal(results[0][i], results[r][i])) << "result " << i << " differs with threads";
  EXPECT_GT(results[0][3].abs().sum().item<float>(), 0.f);
}

TEST(Rasterizer, EmptySetRendersBackground) {
  GaussianSet g = test::random_scene(0, -1, torch::kFloat32, 1);
  RenderOptions opt;
  opt.background = {0.1f, 0.2f, 0.3f};
  const RenderOutput out = render(g, scene_camera(), opt);
  EXPECT_TRUE(torch::allclose(out.rgb[5][7], torch::tensor({0.1f, 0.2f, 0.3f})));
  EXPECT_EQ(out.alpha.abs().max().item<float>(), 0.f);
  EXPECT_EQ(out.depth.abs().max().item<float>(), 0.f);
  // Differentiable with nothing to differentiate.
  g.means.set_requires_grad(true);
  render(g, scene_camera(), opt).rgb.sum().backward();
  EXPECT_EQ(g.means.grad().numel(), 0);
}

TEST(Rasterizer, OnePixelImage) {
  const GaussianSet g = test::random_scene(20, 0, torch::kFloat64, 2);
  const RenderCamera cam = test::opencv_camera(1, 1, 1.0, Eigen::Vector3d(0, 0, -4));
  const RenderOutput fast = render(g, cam), ref = render_reference(g, cam);
  EXPECT_EQ(fast.rgb.sizes(), (std::vector<int64_t>{1, 1, 3}));
  expect_close(fast, ref, 1e-12);
  EXPECT_GT(fast.alpha.item<double>(), 0.5);
}

TEST(Rasterizer, DegenerateGaussiansAreSkipped) {
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  GaussianSet g = test::random_scene(12, 1, torch::kFloat64, 4);
  // 0: behind the camera, 1: NaN mean, 2: NaN colour, 3: inf scale, 4: huge scale, 5: zero
  // scale, 6: zero quaternion, 7: zero opacity, 8: NaN opacity, 9: exactly at the camera.
  g.means[0][2] = -10.0;
  g.means[1][0] = nan;
  g.colors[2][1][0] = nan;
  g.scales[3][1] = inf;
  g.scales[4] = torch::full({3}, 1e200, torch::kFloat64);
  g.scales[5] = torch::zeros({3}, torch::kFloat64);
  g.quats[6] = torch::zeros({4}, torch::kFloat64);
  g.opacities[7] = 0.0;
  g.opacities[8] = nan;
  g.means[9] = torch::tensor({0.1, -0.05, -4.0}, torch::kFloat64);
  for (torch::Tensor* t : {&g.means, &g.quats, &g.scales, &g.opacities, &g.colors}) t->set_requires_grad(true);
  const RenderCamera cam = scene_camera();
  const RenderOutput fast = render(g, cam), ref = render_reference(g, cam);
  EXPECT_TRUE(torch::isfinite(fast.rgb).all().item<bool>());
  EXPECT_TRUE(torch::isfinite(fast.depth).all().item<bool>());
  expect_close(fast, ref, 1e-10);
  (fast.rgb.sum() + fast.alpha.sum() + fast.depth.sum()).backward();
  for (const torch::Tensor* t : {&g.means, &g.quats, &g.scales, &g.opacities, &g.colors})
    EXPECT_TRUE(torch::isfinite(t->grad()).all().item<bool>());
  for (int i : {0, 1, 2, 3, 4, 7, 8, 9}) EXPECT_EQ(g.means.grad()[i].abs().sum().item<double>(), 0.0) << i;
  // The zero-scale and zero-quaternion Gaussians still render (as eps2d blur / identity).
  EXPECT_NE(g.opacities.grad()[5].item<double>(), 0.0);
  EXPECT_NE(g.opacities.grad()[6].item<double>(), 0.0);
}

TEST(Rasterizer, OpacityShapesAndMixedDtypes) {
  GaussianSet g = test::random_scene(30, -1, torch::kFloat32, 8);
  const RenderOutput a = render(g, scene_camera());
  g.opacities = g.opacities.unsqueeze(1).to(torch::kFloat64);  // (N,1), converted to float32
  const RenderOutput b = render(g, scene_camera());
  EXPECT_TRUE(torch::equal(a.rgb, b.rgb));
  EXPECT_EQ(b.rgb.scalar_type(), torch::kFloat32);
}

TEST(Rasterizer, RendersWhereItCan) {
  EXPECT_EQ(render_device(torch::kCPU), torch::Device(torch::kCPU));
  const torch::Device gpu(torch::kCUDA, 0);
  EXPECT_EQ(render_device(gpu), render_has_cuda() ? gpu : torch::Device(torch::kCPU));
}

TEST(Rasterizer, BadInputIsAnError) {
  const GaussianSet good = test::random_scene(5, -1, torch::kFloat32, 9);
  GaussianSet g = good;
  g.quats = torch::zeros({5, 3});
  EXPECT_NE(test::error_message([&] { render(g, scene_camera()); }).find("quats"), std::string::npos);
  g = good;
  g.colors = torch::zeros({5, 4, 3});
  g.sh_degree = 2;
  EXPECT_NE(test::error_message([&] { render(g, scene_camera()); }).find("coefficients"), std::string::npos);
  g = good;
  g.means = g.means.to(torch::kInt32);
  EXPECT_NE(test::error_message([&] { render(g, scene_camera()); }).find("float32"), std::string::npos);
  RenderCamera cam = scene_camera();
  cam.camera.K.width = 0;
  EXPECT_NE(test::error_message([&] { render(good, cam); }).find("size"), std::string::npos);
  cam = scene_camera();
  cam.near_plane = 0;
  EXPECT_NE(test::error_message([&] { render(good, cam); }).find("near"), std::string::npos);
}

}  // namespace
}  // namespace ii
