// The surface placement's steps: depth continued into a hole (a plane stays the plane it was, in
// inverse depth; geometry/continued_depth.h), one flat splat per pixel that tiles the view without gaps, and a
// backing that shows through where a seam in the depth opens a gap in another view
// (geometry/surface_splats.h).
#include <gtest/gtest.h>

#include <cmath>

#include "camera/trajectory.h"
#include "geometry/continued_depth.h"
#include "geometry/surface_splats.h"
#include "render/rasterizer.h"
#include "tensor/image_tensor.h"

namespace ii {
namespace {

Camera test_camera(int width = 64, int height = 48) {
  Camera c;
  c.K = Intrinsics::from_fov(width, height, 60 * M_PI / 180, 2 * std::atan(std::tan(30 * M_PI / 180) * height / width));
  c.c2w = look_at({0, 1.5, 3}, {0, 0, 0}, {0, 1, 0});
  return c;
}

// The z-depth of the plane y = 0 seen from `c` at each pixel (0 where the ray misses it).
torch::Tensor ground_depth(const Camera& c) {
  const Rays rays = compute_rays(c);
  torch::Tensor d = torch::zeros({c.K.height, c.K.width});
  for (int i = 0; i < c.K.height * c.K.width; ++i) {
    const double oy = rays.origin[3 * i + 1], dy = rays.dir_unnorm[3 * i + 1];
    const double t = dy < 0 ? -oy / dy : 0;  // dir_unnorm has camera z -1: t is the z-depth
    d.view({-1})[i] = static_cast<float>(t);
  }
  return d;
}

torch::Tensor square_hole(int height, int width, int top, int left, int size) {
  torch::Tensor hole = torch::zeros({height, width}, torch::kBool);
  hole.slice(0, top, top + size).slice(1, left, left + size).fill_(true);
  return hole;
}

TEST(FillSurface, AHoleInAPlaneIsContinuedAsThatPlane) {
  const Camera c = test_camera();
  const torch::Tensor truth = ground_depth(c);
  ASSERT_GT(truth.min().item<float>(), 0) << "the ground fills the view";
  const torch::Tensor hole = square_hole(48, 64, 20, 16, 20);
  torch::Tensor given = truth.clone();
  given.index_put_({hole}, 0.f);  // what the hole held is not read
  const auto completed = complete_depth(given, torch::ones({48, 64}, torch::kBool), hole);
  ASSERT_TRUE(completed.has_value());
  const double worst = ((*completed - truth).abs() / truth).index({hole}).max().item<double>();
  EXPECT_LT(worst, 1e-3) << "largest relative depth error in the hole";
  EXPECT_TRUE(torch::equal(completed->index({hole.logical_not()}), truth.index({hole.logical_not()})));
}

TEST(FillSurface, NothingKnownAroundTheHoleIsNoSurface) {
  const torch::Tensor hole = square_hole(16, 16, 4, 4, 8);
  EXPECT_FALSE(complete_depth(torch::ones({16, 16}), torch::zeros({16, 16}, torch::kBool), hole).has_value());
  // Pixels left out (neither known nor in the hole) do not pull the hole's depth: one known
  // pixel at depth 2 decides it all.
  torch::Tensor known = torch::zeros({16, 16}, torch::kBool);
  known[4][3] = true;
  const auto completed = complete_depth(torch::full({16, 16}, 2.f), known, hole);
  ASSERT_TRUE(completed.has_value());
  EXPECT_NEAR(completed->index({hole}).min().item<double>(), 2, 1e-3);
  EXPECT_NEAR(completed->index({hole}).max().item<double>(), 2, 1e-3);
}

TEST(FillSurface, OneSplatPerPixelTilesTheViewInItsColours) {
  const Camera c = test_camera();
  const torch::Tensor depth = ground_depth(c);
  const torch::Tensor take = square_hole(48, 64, 10, 10, 30);
  Image colour(64, 48, 3);
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x) {
      colour.at(y, x, 0) = static_cast<float>(x) / 63.f;
      colour.at(y, x, 1) = static_cast<float>(y) / 47.f;
      colour.at(y, x, 2) = 0.5f;
    }
  const GaussianSet g = surface_gaussians(c, depth, take, colour);
  ASSERT_EQ(g.size(), take.sum().item<int64_t>());
  // On the plane: every centre at y = 0, the flat axis along the plane's normal.
  EXPECT_LT(g.means.select(1, 1).abs().max().item<double>(), 1e-4);
  const RenderOutput out = render(g, {c});
  const torch::Tensor alpha = out.alpha.squeeze(2);
  // Inside the square (a pixel in from its edge) nothing of the background shows, and the
  // colours are the picture's.
  const torch::Tensor inner = square_hole(48, 64, 12, 12, 26);
  EXPECT_GT(alpha.index({inner}).min().item<double>(), 0.9);
  const torch::Tensor want = image_to_tensor(colour)[0].permute({1, 2, 0});
  const double error = (out.rgb - want).abs().index({inner}).mean().item<double>();
  EXPECT_LT(error, 0.03);
  // Three pixels out from it nothing was added (a splat's tail reaches about two).
  const torch::Tensor far = square_hole(48, 64, 10, 10, 30).logical_not();
  far.slice(0, 7, 43).slice(1, 7, 43).fill_(false);
  EXPECT_LT(alpha.index({far}).max().item<double>(), 0.05);
}

// A surface with a step in its depth, seen from a camera moved to the side: between the front
// splats on either side of the step the background shows; with the backing behind them it does not,
// and where the front splats are seen the backing changes nothing.
TEST(FillSurface, TheBackingCoversWhatASeamLetsThrough) {
  const Camera c = test_camera();
  torch::Tensor depth = ground_depth(c);
  const torch::Tensor take = square_hole(48, 64, 10, 10, 30);
  depth.slice(1, 25, 64).mul_(1.2f);  // the right part 20 % farther: a seam at column 25
  const Image colour(64, 48, 3, 0.4f);
  const GaussianSet front = surface_gaussians(c, depth, take, colour);
  const GaussianSet back = backing_gaussians(c, depth, take, colour);
  EXPECT_EQ(back.size(), 15 * 15);  // the 30 x 30 square at half the size
  Camera side = c;
  side.c2w = look_at({1.2, 1.5, 3}, {0, 0, 0}, {0, 1, 0});
  // The seam's pixels in the side view: inside the square's footprint there, not covered.
  const torch::Tensor front_alpha = render(front, {side}).alpha.squeeze(2);
  const torch::Tensor both_alpha = render(joined(front, back), {side}).alpha.squeeze(2);
  const torch::Tensor footprint = render(back, {side}).alpha.squeeze(2) > 0.9;  // well inside the backing
  const int64_t open_front = footprint.logical_and(front_alpha < 0.5).sum().item<int64_t>();
  const int64_t open_both = footprint.logical_and(both_alpha < 0.5).sum().item<int64_t>();
  EXPECT_GT(open_front, 0) << "the front splats alone let the background through at the seam";
  EXPECT_EQ(open_both, 0) << open_front << " pixels open with the front splats alone";
  // From the reference camera itself the backing is hidden: the same picture.
  const RenderOutput alone = render(front, {c}), with = render(joined(front, back), {c});
  const torch::Tensor inner = square_hole(48, 64, 12, 12, 26);
  EXPECT_LT((alone.rgb - with.rgb).abs().index({inner}).max().item<double>(), 0.02);
}

}  // namespace
}  // namespace ii
