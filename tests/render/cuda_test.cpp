// The CUDA kernels against the CPU renderer (needs a CUDA build of LibTorch and a GPU;
// skipped otherwise).
#include <gtest/gtest.h>

#include <limits>

#include "render/rasterizer.h"
#include "render/render_test_util.h"
#include "test_support.h"

namespace ii {
namespace {
// A namespace of its own: the folder's test files are compiled together (CMake's unity build).
namespace cuda_test {

#define II_REQUIRE_CUDA_RASTERIZER() \
  II_REQUIRE_CUDA();                  \
  if (!render_has_cuda()) GTEST_SKIP() << "built without the CUDA rasterizer (no nvcc at configure time)"

std::vector<torch::Tensor*> params(GaussianSet& g) {
  return {&g.means, &g.quats, &g.scales, &g.opacities, &g.colors};
}

struct Result {
  RenderOutput out;
  std::vector<torch::Tensor> grads;
};

Result run(GaussianSet g, const RenderCamera& cam, const RenderOptions& opt, const torch::Device& device) {
  g = g.to(device);
  for (torch::Tensor* t : params(g)) *t = t->detach().clone().set_requires_grad(true);
  Result r;
  r.out = render(g, cam, opt);
  torch::manual_seed(5);
  const auto w = torch::randn(r.out.rgb.sizes(), r.out.rgb.options().device(torch::kCPU)).to(device);
  ((r.out.rgb * w).sum() + 0.5 * r.out.alpha.sum() + 0.1 * r.out.depth.sum()).backward();
  for (torch::Tensor* t : params(g)) r.grads.push_back(t->grad().cpu());
  r.out.rgb = r.out.rgb.cpu();
  r.out.alpha = r.out.alpha.cpu();
  r.out.depth = r.out.depth.cpu();
  return r;
}

void compare(const GaussianSet& g, const RenderCamera& cam, const RenderOptions& opt = {}) {
  const Result cpu = run(g, cam, opt, torch::kCPU), gpu = run(g, cam, opt, torch::kCUDA);
  EXPECT_LT(test::max_abs_diff(cpu.out.rgb, gpu.out.rgb), 1e-5);
  EXPECT_LT(test::max_abs_diff(cpu.out.alpha, gpu.out.alpha), 1e-5);
  EXPECT_LT(test::max_abs_diff(cpu.out.depth * cpu.out.alpha, gpu.out.depth * gpu.out.alpha), 1e-4);
  const char* names[] = {"means", "quats", "scales", "opacities", "colors"};
  for (size_t i = 0; i < 5; ++i) {
    const double scale = std::max(test::max_abs(cpu.grads[i]), 1e-12);
    EXPECT_LT(test::max_abs_diff(cpu.grads[i], gpu.grads[i]) / scale, 1e-4) << names[i];
  }
}

TEST(RenderCuda, MatchesCpuRgb) {
  II_REQUIRE_CUDA_RASTERIZER();
  compare(test::random_scene(500, -1, torch::kFloat32, 1, 1.2, 0.08),
          test::opencv_camera(100, 70, 80, Eigen::Vector3d(0, 0, -4)));
}

TEST(RenderCuda, MatchesCpuShDenseScene) {
  II_REQUIRE_CUDA_RASTERIZER();
  RenderOptions opt;
  opt.background = {0.1f, 0.4f, 0.7f};
  compare(test::random_scene(5000, 3, torch::kFloat32, 2, 1.5, 0.03),
          test::opencv_camera(200, 130, 150, Eigen::Vector3d(0.2, 0.1, -4)), opt);
}

TEST(RenderCuda, MatchesCpuDouble) {
  II_REQUIRE_CUDA_RASTERIZER();
  compare(test::random_scene(300, 2, torch::kFloat64, 3), test::opencv_camera(64, 48, 50, Eigen::Vector3d(0, 0, -4)));
}

// The scene bounds (orbit videos, refinement's coverage) of splats on the GPU.
TEST(RenderCuda, VisibleBoundsOfSplatsOnTheGpu) {
  II_REQUIRE_CUDA_RASTERIZER();
  const GaussianSet g = test::random_scene(500, -1, torch::kFloat32, 1, 1.2, 0.08);
  const BoundingSphere cpu = visible_bounds(g), gpu = visible_bounds(g.to(torch::kCUDA));
  EXPECT_LT((cpu.centre - gpu.centre).norm(), 1e-6);
  EXPECT_NEAR(cpu.radius, gpu.radius, 1e-6);
}

TEST(RenderCuda, Golden) {
  II_REQUIRE_CUDA_RASTERIZER();
  II_REQUIRE_SHARED(path, "data/render-golden/basic_case.safetensors");
  const test::GoldenCase c = test::load_golden(path);
  const RenderOutput out = render(c.gaussians.to(torch::kCUDA), c.camera, c.options);
  EXPECT_GE(test::psnr(out.rgb.cpu(), c.image.narrow(2, 0, 3)), 45.0);
}

TEST(RenderCuda, DegenerateAndEmpty) {
  II_REQUIRE_CUDA_RASTERIZER();
  GaussianSet g = test::random_scene(8, 0, torch::kFloat32, 4);
  g.means[0][0] = std::numeric_limits<float>::quiet_NaN();
  g.means[1][2] = -10.f;
  g.scales[2] = torch::zeros({3});
  compare(g, test::opencv_camera(33, 17, 30, Eigen::Vector3d(0, 0, -4)));
  compare(test::random_scene(0, -1, torch::kFloat32, 5), test::opencv_camera(20, 20, 20, Eigen::Vector3d(0, 0, -4)));
  compare(test::random_scene(5, -1, torch::kFloat32, 6), test::opencv_camera(1, 1, 1, Eigen::Vector3d(0, 0, -4)));
}

}  // namespace cuda_test
}  // namespace
}  // namespace ii
