// The analytic backward of render() against central finite differences (double precision)
// and against LibTorch's autograd through render_reference().
#include <gtest/gtest.h>

#include "render/rasterizer.h"
#include "render/render_test_util.h"
#include "test_support.h"

namespace ii {
namespace {
// A namespace of its own: the folder's test files are compiled together (CMake's unity build).
namespace gradient_test {

std::vector<torch::Tensor*> params(GaussianSet& g) {
  return {&g.means, &g.quats, &g.scales, &g.opacities, &g.colors};
}
const char* const kNames[] = {"means", "quats", "scales", "opacities", "colors"};

// A scalar of all three outputs with fixed random weights, so every output's gradient path
// is exercised.
struct Loss {
  torch::Tensor w_rgb, w_alpha, w_depth;
  Loss(int h, int w) {
    torch::manual_seed(99);
    const auto o = torch::TensorOptions().dtype(torch::kFloat64);
    w_rgb = torch::randn({h, w, 3}, o);
    w_alpha = torch::randn({h, w, 1}, o);
    w_depth = 0.1 * torch::randn({h, w, 1}, o);
  }
  torch::Tensor operator()(const RenderOutput& r) const {
    return (r.rgb * w_rgb).sum() + (r.alpha * w_alpha).sum() + (r.depth * w_depth).sum();
  }
};

std::vector<torch::Tensor> analytic_grads(GaussianSet g, const RenderCamera& cam, const RenderOptions& opt,
                                          const Loss& loss, bool reference) {
  for (torch::Tensor* t : params(g)) *t = t->detach().clone().set_requires_grad(true);
  const RenderOutput out = reference ? render_reference(g, cam, opt) : render(g, cam, opt);
  loss(out).backward();
  std::vector<torch::Tensor> grads;
  for (torch::Tensor* t : params(g)) grads.push_back(t->grad());
  return grads;
}

struct GradCase {
  GaussianSet g;
  RenderCamera cam;
  RenderOptions opt;
};

GradCase small_case(int sh_degree, uint64_t seed) {
  GradCase c;
  // A few large Gaussians over a 16x16 image; they overlap, so order and transmittance
  // matter, and a few sit near the edge where the Jacobian clamp applies.
  c.g = test::random_scene(6, sh_degree, torch::kFloat64, seed, 1.3, 0.35);
  c.cam = test::opencv_camera(16, 16, 14.0, Eigen::Vector3d(0.05, 0.1, -4.0));
  c.opt.background = {0.3f, 0.6f, 0.1f};
  return c;
}

// Central differences; entries whose step crosses a discontinuity (a splat crossing the
// 1/255 cut-off, a tile edge, a change of depth order) show up as isolated outliers, so a
// small fraction of misses is tolerated while the rest must agree tightly.
void check_finite_differences(GradCase c) {
  const Loss loss(c.cam.camera.K.height, c.cam.camera.K.width);
  const std::vector<torch::Tensor> ana = analytic_grads(c.g, c.cam, c.opt, loss, false);
  torch::NoGradGuard no_grad;
  const double h = 1e-6;
  int checked = 0, missed = 0, nonzero = 0;
  for (size_t p = 0; p < 5; ++p) {
    torch::Tensor& t = *params(c.g)[p];
    t = t.clone();
    auto flat = t.view({-1});
    const auto a = ana[p].reshape({-1});
    for (int64_t i = 0; i < flat.numel(); ++i) {
      const double x0 = flat[i].item<double>();
      flat[i] = x0 + h;
      const double up = loss(render(c.g, c.cam, c.opt)).item<double>();
      flat[i] = x0 - h;
      const double down = loss(render(c.g, c.cam, c.opt)).item<double>();
      flat[i] = x0;
      const double fd = (up - down) / (2 * h), an = a[i].item<double>();
      ++checked;
      nonzero += std::abs(an) > 1e-6;
      if (std::abs(fd - an) > 1e-5 + 1e-4 * std::abs(an)) {
        ++missed;
        ADD_FAILURE_AT(__FILE__, __LINE__) << kNames[p] << "[" << i << "]: analytic " << an << " vs fd " << fd;
        if (missed > 5) return;
      }
    }
  }
  EXPECT_GE(checked, 84);
  EXPECT_GT(nonzero, checked / 2) << "most parameters should matter in this scene";
}

TEST(RenderGradient, FiniteDifferencesRgb) { check_finite_differences(small_case(-1, 21)); }
TEST(RenderGradient, FiniteDifferencesSh1) { check_finite_differences(small_case(1, 22)); }
TEST(RenderGradient, FiniteDifferencesSh3) { check_finite_differences(small_case(3, 23)); }

// Gaussians beyond the image edge: the Jacobian's x/z, y/z clamp is active.
TEST(RenderGradient, FiniteDifferencesFovClamp) {
  GradCase c = small_case(2, 24);
  c.g.means.select(1, 0).add_(torch::tensor({3.0, -3.2, 0.0, 2.9, 0.0, 0.0}, torch::kFloat64));
  c.g.scales.mul_(2.0);
  check_finite_differences(c);
}

// Opacities near 1 and many layers: the 0.999 clamp and the transmittance stop take part.
TEST(RenderGradient, FiniteDifferencesOpaqueLayers) {
  GradCase c = small_case(0, 25);
  c.g.opacities = torch::tensor({0.9995, 0.99, 0.98, 0.999, 0.97, 0.995}, torch::kFloat64);
  c.g.means.select(1, 0).mul_(0.2);
  c.g.means.select(1, 1).mul_(0.2);
  check_finite_differences(c);
}

// The analytic backward against autograd through the plain reference renderer, on a larger
// scene (hundreds of Gaussians, several tiles).
TEST(RenderGradient, MatchesReferenceAutograd) {
  for (int degree : {-1, 3}) {
    SCOPED_TRACE("sh_degree " + std::to_string(degree));
    GradCase c;
    c.g = test::random_scene(150, degree, torch::kFloat64, 30 + degree, 1.2, 0.12);
    c.cam = test::opencv_camera(40, 36, 30.0, Eigen::Vector3d(0.0, 0.0, -4.0));
    const Loss loss(36, 40);
    const auto fast = analytic_grads(c.g, c.cam, c.opt, loss, false);
    const auto ref = analytic_grads(c.g, c.cam, c.opt, loss, true);
    for (size_t p = 0; p < 5; ++p) {
      const double scale = ref[p].abs().max().item<double>();
      EXPECT_GT(scale, 0) << kNames[p];
      EXPECT_LT(test::max_abs_diff(fast[p], ref[p]), 1e-9 * std::max(1.0, scale)) << kNames[p];
    }
  }
}

// Float gradients agree with double ones to float precision.
TEST(RenderGradient, FloatMatchesDouble) {
  GradCase c = small_case(3, 40);
  const Loss loss(16, 16);
  const auto d = analytic_grads(c.g, c.cam, c.opt, loss, false);
  for (torch::Tensor* t : params(c.g)) *t = t->to(torch::kFloat32);
  const auto f = analytic_grads(c.g, c.cam, c.opt, loss, false);
  for (size_t p = 0; p < 5; ++p) {
    EXPECT_EQ(f[p].scalar_type(), torch::kFloat32);
    const double scale = d[p].abs().max().item<double>();
    EXPECT_LT(test::max_abs_diff(f[p], d[p]), 1e-4 * std::max(1.0, scale)) << kNames[p];
  }
}

// Many small, nearly opaque Gaussians over several tiles (pixels reaching the 1e-4
// transmittance stop and the 0.999 alpha clamp): float, on the tile loops this CPU runs (AVX2
// where it has them), agrees with double (always the scalar loops) in images and gradients.
TEST(RenderGradient, FloatMatchesDoubleInADenseScene) {
  GradCase c;
  c.g = test::random_scene(400, -1, torch::kFloat64, 3, 1.2, 0.08);
  c.g.opacities = c.g.opacities.clamp_max(0.9) + 0.0995;  // up to 0.9995 > 0.999
  c.cam = test::opencv_camera(45, 38, 30.0, Eigen::Vector3d(0.05, 0.1, -4.0));
  const Loss loss(38, 45);
  const RenderOutput d_out = render(c.g, c.cam, c.opt);
  const auto d = analytic_grads(c.g, c.cam, c.opt, loss, false);
  for (torch::Tensor* t : params(c.g)) *t = t->to(torch::kFloat32);
  const RenderOutput f_out = render(c.g, c.cam, c.opt);
  EXPECT_GT(d_out.alpha.max().item<double>(), 1 - 1e-4 - 1e-3);  // some pixels reach the stop
  EXPECT_LT(test::max_abs_diff(f_out.rgb, d_out.rgb), 1e-5);  // 1e-6 measured
  EXPECT_LT(test::max_abs_diff(f_out.alpha, d_out.alpha), 1e-5);
  const auto f = analytic_grads(c.g, c.cam, c.opt, loss, false);
  for (size_t p = 0; p < 5; ++p) {
    const double scale = d[p].abs().max().item<double>();
    EXPECT_LT(test::max_abs_diff(f[p], d[p]), 3e-5 * std::max(1.0, scale)) << kNames[p];  // 5e-6 measured
  }
}

// Gradients reach tensors that were converted (float64 opacities (N,1) into a float32 set).
TEST(RenderGradient, ThroughConversions) {
  GaussianSet g = test::random_scene(10, -1, torch::kFloat32, 41);
  torch::Tensor op = g.opacities.to(torch::kFloat64).unsqueeze(1).detach().set_requires_grad(true);
  g.opacities = op;
  render(g, test::opencv_camera(16, 16, 14.0, Eigen::Vector3d(0, 0, -4))).rgb.sum().backward();
  ASSERT_TRUE(op.grad().defined());
  EXPECT_EQ(op.grad().sizes(), op.sizes());
  EXPECT_GT(op.grad().abs().sum().item<double>(), 0);
}

}  // namespace gradient_test
}  // namespace
}  // namespace ii
