// The renderer against gsplat's own output (brush's golden cases, rendered by gsplat on CUDA).
#include <gtest/gtest.h>

#include "render/rasterizer.h"
#include "render/render_test_util.h"
#include "test_support.h"

namespace ii {
namespace {

void check_golden(const std::filesystem::path& path) {
  const test::GoldenCase c = test::load_golden(path);
  for (const bool reference : {false, true}) {
    SCOPED_TRACE(reference ? "render_reference" : "render");
    const RenderOutput out = reference ? render_reference(c.gaussians, c.camera, c.options)
                                       : render(c.gaussians, c.camera, c.options);
    const torch::Tensor want_rgb = c.image.narrow(2, 0, 3), want_alpha = c.image.narrow(2, 3, 1);
    const double p_rgb = test::psnr(out.rgb, want_rgb), p_alpha = test::psnr(out.alpha, want_alpha);
    EXPECT_GE(p_rgb, 45.0);
    EXPECT_GE(p_alpha, 45.0);
    // brush's own tolerance for these files: 1e-5 absolute plus 1% of the reference value.
    const auto tol = 1e-5 + 0.01 * c.image.abs();
    const auto got = torch::cat({out.rgb, out.alpha}, 2);
    const int64_t bad = ((got - c.image).abs() > tol).sum().item<int64_t>();
    EXPECT_EQ(bad, 0) << "max |diff| " << test::max_abs_diff(got, c.image) << ", PSNR rgb " << p_rgb
                      << " alpha " << p_alpha;
    EXPECT_GT(c.image.narrow(2, 3, 1).max().item<float>(), 0.1f) << "golden image is empty?";
    std::printf("%s %s: PSNR rgb %.1f dB, alpha %.1f dB, max |diff| %.2g\n", path.filename().string().c_str(),
                reference ? "render_reference" : "render", p_rgb, p_alpha, test::max_abs_diff(got, c.image));
  }
}

TEST(RenderGolden, TinyCase) {
  II_REQUIRE_SHARED(path, "data/render-golden/tiny_case.safetensors");
  check_golden(path);
}

TEST(RenderGolden, BasicCase) {
  II_REQUIRE_SHARED(path, "data/render-golden/basic_case.safetensors");
  check_golden(path);
}

// The same scene in double precision agrees with float to float rounding.
TEST(RenderGolden, DoubleMatchesFloat) {
  II_REQUIRE_SHARED(path, "data/render-golden/basic_case.safetensors");
  test::GoldenCase c = test::load_golden(path);
  const RenderOutput f = render(c.gaussians, c.camera, c.options);
  GaussianSet d = c.gaussians;
  for (torch::Tensor* t : {&d.means, &d.quats, &d.scales, &d.opacities, &d.colors}) *t = t->to(torch::kFloat64);
  const RenderOutput o = render(d, c.camera, c.options);
  EXPECT_EQ(o.rgb.scalar_type(), torch::kFloat64);
  EXPECT_LT(test::max_abs_diff(f.rgb, o.rgb), 1e-5);
  EXPECT_LT(test::max_abs_diff(f.alpha, o.alpha), 1e-5);
}

}  // namespace
}  // namespace ii
