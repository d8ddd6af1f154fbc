// PSNR, SSIM and their masked / bounding-box variants against values computed by hand.
#include <gtest/gtest.h>

#include <cmath>

#include "eval/metrics.h"
#include "test_support.h"

namespace ii {
namespace {

torch::Tensor filled(int64_t h, int64_t w, double value, torch::ScalarType dtype = torch::kFloat32) {
  return torch::full({1, 3, h, w}, value, torch::TensorOptions().dtype(dtype));
}

TEST(Psnr, OfAKnownMeanSquaredError) {
  // Every value differs by 0.1: MSE 0.01, PSNR exactly 20 dB.
  EXPECT_NEAR(psnr(filled(16, 16, 0.2), filled(16, 16, 0.3))[0].item<double>(), 20.0, 1e-4);
  // Half the pixels differ by 0.5: MSE 0.125.
  torch::Tensor b = filled(8, 8, 0.0);
  b.narrow(3, 0, 4).fill_(0.5);
  EXPECT_NEAR(psnr(filled(8, 8, 0.0), b)[0].item<double>(), -10 * std::log10(0.125), 1e-5);
  EXPECT_NEAR(mse(filled(8, 8, 0.0), b)[0].item<double>(), 0.125, 1e-7);
}

TEST(Psnr, IdenticalImagesAreInfinite) {
  const torch::Tensor a = torch::rand({2, 3, 9, 7});
  const torch::Tensor p = psnr(a, a);
  ASSERT_EQ(p.sizes(), (c10::IntArrayRef{2}));
  EXPECT_TRUE(std::isinf(p[0].item<double>()) && p[0].item<double>() > 0);
}

TEST(Psnr, ClampsToTheDataRange) {
  // 1.5 counts as 1 and -1 as 0: both images become 1 vs 0, MSE 1, PSNR 0.
  EXPECT_NEAR(psnr(filled(4, 4, 1.5), filled(4, 4, -1.0))[0].item<double>(), 0.0, 1e-6);
}

TEST(Psnr, MaskedMeanOverTheMaskOnly) {
  torch::Tensor a = filled(10, 10, 0.5), b = a.clone();
  torch::Tensor mask = torch::zeros({1, 1, 10, 10});
  mask.narrow(2, 2, 3).narrow(3, 4, 5).fill_(1);  // 15 pixels
  b.narrow(2, 2, 3).narrow(3, 4, 5).add_(0.1);    // the error lies exactly on the mask
  EXPECT_NEAR(masked_psnr(a, b, mask)[0].item<double>(), 20.0, 1e-4);
  EXPECT_NEAR(psnr(a, b)[0].item<double>(), -10 * std::log10(0.01 * 15 / 100), 1e-4);
  // Mask values are thresholded at 0.5; (H, W) and (1, H, W) masks work too.
  EXPECT_NEAR(masked_psnr(a, b, mask[0][0] * 0.8)[0].item<double>(), 20.0, 1e-4);
  EXPECT_NEAR(masked_psnr(a, b, mask[0])[0].item<double>(), 20.0, 1e-4);
  EXPECT_TRUE(std::isnan(masked_psnr(a, b, torch::zeros({10, 10}))[0].item<double>()));
}

// SSIM at one position by the textbook formula: Gaussian-weighted statistics of the 11x11
// window centred on (y, x), per channel, averaged over channels.
double direct_ssim_at(const torch::Tensor& a, const torch::Tensor& b, int y, int x) {
  double weights[11];
  double total = 0;
  for (int i = 0; i < 11; ++i) total += weights[i] = std::exp(-(i - 5) * (i - 5) / (2 * 1.5 * 1.5));
  for (double& w : weights) w /= total;
  const auto pa = a.to(torch::kFloat64).contiguous(), pb = b.to(torch::kFloat64).contiguous();
  const auto A = pa.accessor<double, 4>(), B = pb.accessor<double, 4>();
  double sum = 0;
  for (int c = 0; c < 3; ++c) {
    double ma = 0, mb = 0, saa = 0, sbb = 0, sab = 0;
    for (int i = 0; i < 11; ++i)
      for (int j = 0; j < 11; ++j) {
        const double w = weights[i] * weights[j], u = A[0][c][y - 5 + i][x - 5 + j], v = B[0][c][y - 5 + i][x - 5 + j];
        ma += w * u;
        mb += w * v;
        saa += w * u * u;
        sbb += w * v * v;
        sab += w * u * v;
      }
    const double va = saa - ma * ma, vb = sbb - mb * mb, cov = sab - ma * mb;
    const double c1 = 1e-4, c2 = 9e-4;
    sum += (2 * ma * mb + c1) * (2 * cov + c2) / ((ma * ma + mb * mb + c1) * (va + vb + c2));
  }
  return sum / 3;
}

TEST(Ssim, IdentityIsOne) {
  torch::manual_seed(1);
  const torch::Tensor a = torch::rand({2, 3, 20, 24});
  const torch::Tensor s = ssim(a, a);
  ASSERT_EQ(s.sizes(), (c10::IntArrayRef{2}));
  EXPECT_NEAR(s[0].item<double>(), 1.0, 1e-6);
  EXPECT_NEAR(s[1].item<double>(), 1.0, 1e-6);
  EXPECT_NEAR(ssim(a[0], a[0])[0].item<double>(), 1.0, 1e-6);  // (C, H, W) too
}

TEST(Ssim, ConstantImagesGiveTheLuminanceTerm) {
  // No variance: SSIM = (2ab + C1) / (a² + b² + C1) everywhere.
  const double a = 0.5, b = 0.25, c1 = 1e-4;
  EXPECT_NEAR(ssim(filled(16, 16, a), filled(16, 16, b))[0].item<double>(), (2 * a * b + c1) / (a * a + b * b + c1),
              1e-6);
}

TEST(Ssim, MapMatchesTheTextbookFormulaOnValidPositions) {
  torch::manual_seed(2);
  const torch::Tensor a = torch::rand({1, 3, 17, 19}, torch::kFloat64);
  const torch::Tensor b = (a * 0.7 + 0.3 * torch::rand({1, 3, 17, 19}, torch::kFloat64)).clamp(0, 1);
  const torch::Tensor map = ssim_map(a, b);
  ASSERT_EQ(map.sizes(), (c10::IntArrayRef{1, 1, 7, 9}));  // windows entirely inside
  for (auto [y, x] : {std::pair{5, 5}, std::pair{8, 13}, std::pair{11, 9}})
    EXPECT_NEAR(map[0][0][y - 5][x - 5].item<double>(), direct_ssim_at(a, b, y, x), 1e-10) << y << "," << x;
  EXPECT_NEAR(ssim(a, b)[0].item<double>(), map.mean().item<double>(), 1e-12);
}

TEST(Ssim, IsDifferentiable) {
  torch::manual_seed(3);
  const torch::Tensor b = torch::rand({1, 3, 12, 12}, torch::kFloat64);
  torch::Tensor a = torch::rand({1, 3, 12, 12}, torch::kFloat64).requires_grad_(true);
  const torch::Tensor loss = 1 - ssim(a, b).mean();
  loss.backward();
  const double analytic = a.grad()[0][1][6][5].item<double>();
  const double h = 1e-6;
  torch::Tensor plus = a.detach().clone(), minus = a.detach().clone();
  plus[0][1][6][5] += h;
  minus[0][1][6][5] -= h;
  const double numeric = ((1 - ssim(plus, b)[0]) - (1 - ssim(minus, b)[0])).item<double>() / (2 * h);
  EXPECT_NEAR(analytic, numeric, 1e-6 * std::max(1.0, std::abs(numeric)));
  EXPECT_NE(analytic, 0.0);
}

TEST(Ssim, MaskedMeanOfTheMap) {
  torch::manual_seed(4);
  const torch::Tensor a = torch::rand({1, 3, 20, 20}), b = torch::rand({1, 3, 20, 20});
  EXPECT_NEAR(masked_ssim(a, b, torch::ones({20, 20}))[0].item<double>(), ssim(a, b)[0].item<double>(), 1e-6);
  // Mask rows 7..9, columns 6..13: map positions (rows 2..4, columns 1..8) of the valid map.
  torch::Tensor mask = torch::zeros({20, 20});
  mask.narrow(0, 7, 3).narrow(1, 6, 8).fill_(1);
  const double expected = ssim_map(a, b)[0][0].narrow(0, 2, 3).narrow(1, 1, 8).mean().item<double>();
  EXPECT_NEAR(masked_ssim(a, b, mask)[0].item<double>(), expected, 1e-6);
  // A mask only within 5 pixels of the border has no valid position.
  torch::Tensor border = torch::zeros({20, 20});
  border[0][0] = 1;
  EXPECT_TRUE(std::isnan(masked_ssim(a, b, border)[0].item<double>()));
  // One map, several masks (eval's SSIM, masked and outside the mask): the same values.
  const torch::Tensor map = ssim_map(a, b);
  EXPECT_TRUE(torch::equal(masked_ssim_of_map(map, mask), masked_ssim(a, b, mask)));
  EXPECT_TRUE(torch::equal(masked_ssim_of_map(map, 1 - mask), masked_ssim(a, b, 1 - mask)));
  EXPECT_EQ(test::error_message([&] { masked_ssim_of_map(map, torch::ones({10, 10})); }),
            "masked ssim: mask of shape [10, 10] does not fit images of shape [1, C, 20, 20] (expected (N or 1, 1, "
            "H, W))");
}

TEST(BoundingBox, OfTensorAndImageMasks) {
  torch::Tensor mask = torch::zeros({1, 1, 12, 16});
  mask[0][0][3][5] = 1;
  mask[0][0][6][9] = 1;
  mask[0][0][4][7] = 0.4;  // below the threshold
  const auto box = mask_bounding_box(mask);
  ASSERT_TRUE(box);
  EXPECT_EQ(box->x0, 5);
  EXPECT_EQ(box->x1, 10);
  EXPECT_EQ(box->y0, 3);
  EXPECT_EQ(box->y1, 7);
  Image image(16, 12, 1);
  image.at(3, 5) = 1;
  image.at(6, 9) = 1;
  const auto box2 = mask_bounding_box(image);
  ASSERT_TRUE(box2);
  EXPECT_EQ(std::tie(box2->x0, box2->y0, box2->x1, box2->y1), std::tie(box->x0, box->y0, box->x1, box->y1));
  EXPECT_FALSE(mask_bounding_box(torch::zeros({5, 5})));
  EXPECT_FALSE(mask_bounding_box(Image(4, 4, 1)));
}

TEST(BoundingBox, GrowStaysInsideTheImage) {
  const PixelBox centred = grow_box({10, 10, 12, 13}, 6, 7, 40, 30);
  EXPECT_EQ(std::tie(centred.x0, centred.x1, centred.y0, centred.y1), std::make_tuple(8, 14, 8, 15));
  const PixelBox corner = grow_box({0, 0, 2, 2}, 11, 11, 40, 30);
  EXPECT_EQ(std::tie(corner.x0, corner.x1, corner.y0, corner.y1), std::make_tuple(0, 11, 0, 11));
  const PixelBox far_corner = grow_box({38, 28, 40, 30}, 11, 11, 40, 30);
  EXPECT_EQ(std::tie(far_corner.x0, far_corner.x1, far_corner.y0, far_corner.y1), std::make_tuple(29, 40, 19, 30));
  const PixelBox clamped = grow_box({1, 1, 3, 3}, 50, 50, 8, 6);
  EXPECT_EQ(std::tie(clamped.x0, clamped.x1, clamped.y0, clamped.y1), std::make_tuple(0, 8, 0, 6));
  const PixelBox large = grow_box({2, 3, 30, 20}, 11, 11, 40, 30);  // already large enough
  EXPECT_EQ(std::tie(large.x0, large.x1, large.y0, large.y1), std::make_tuple(2, 30, 3, 20));
}

TEST(BoundingBox, PsnrAndSsimOnTheBox) {
  torch::Tensor a = filled(30, 40, 0.5), b = a.clone();
  torch::Tensor mask = torch::zeros({30, 40});
  mask.narrow(0, 10, 4).narrow(1, 20, 5).fill_(1);
  // Error 0.1 on the mask's box only (a 4x5 box).
  b.narrow(2, 10, 4).narrow(3, 20, 5).add_(0.1);
  EXPECT_NEAR(box_psnr(a, b, mask), 20.0, 1e-4);
  // SSIM on the box grown to 11x11: rows 7..17, columns 17..27.
  const PixelBox grown{17, 7, 28, 18};
  EXPECT_NEAR(box_ssim(a, b, mask), ssim(crop_to_box(a, grown), crop_to_box(b, grown))[0].item<double>(), 1e-7);
  EXPECT_LT(box_ssim(a, b, mask), ssim(a, b)[0].item<double>());
  EXPECT_TRUE(std::isnan(box_psnr(a, b, torch::zeros({30, 40}))));
  // Both at once for a box known on the host (eval: no wait for a GPU).
  const torch::Tensor both = box_psnr_ssim(a, b, *mask_bounding_box(mask));
  EXPECT_EQ(both[0].item<float>(), static_cast<float>(box_psnr(a, b, mask)));
  EXPECT_EQ(both[1].item<float>(), static_cast<float>(box_ssim(a, b, mask)));
  // The box's SSIM read from the whole image's map: the same within float rounding.
  torch::manual_seed(6);
  const torch::Tensor c = torch::rand({1, 3, 30, 40}), d = torch::rand({1, 3, 30, 40});
  const torch::Tensor from_map = box_psnr_ssim(c, d, *mask_bounding_box(mask), ssim_map(c, d));
  EXPECT_EQ(from_map[0].item<float>(), static_cast<float>(box_psnr(c, d, mask)));
  EXPECT_NEAR(from_map[1].item<float>(), box_ssim(c, d, mask), 1e-6);
}

TEST(Metrics, BadInputsNameTheProblem) {
  EXPECT_EQ(test::error_message([] { psnr(filled(4, 4, 0), filled(4, 5, 0)); }),
            "psnr: the images differ in shape: [1, 3, 4, 4] vs [1, 3, 4, 5]");
  EXPECT_EQ(test::error_message([] { ssim(filled(10, 30, 0), filled(10, 30, 0)); }),
            "ssim: images of 30x10 pixels are smaller than the 11x11 SSIM window");
  EXPECT_EQ(test::error_message([] {
              ssim(torch::zeros({4, 4}), torch::zeros({4, 4}));
            }),
            "ssim: first image must be (N, C, H, W) or (C, H, W), got shape [4, 4]");
  EXPECT_EQ(test::error_message([] {
              masked_psnr(filled(4, 4, 0), filled(4, 4, 0), torch::zeros({1, 1, 4, 3}));
            }),
            "masked psnr: mask of shape [1, 1, 4, 3] does not fit images of shape [1, 3, 4, 4] (expected (N or 1, 1, "
            "H, W))");
  EXPECT_EQ(test::error_message([] {
              crop_to_box(torch::zeros({3, 4, 4}), PixelBox{2, 2, 6, 3});
            }),
            "crop: box [2, 6) x [2, 3) is empty or outside the 4x4 image");
}

}  // namespace
}  // namespace ii
