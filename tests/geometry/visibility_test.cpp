// Visibility: a camera 3 units from the wall z = 0 that saw the wall at depth 3 everywhere but a
// masked-off corner. A point 10 % nearer than the wall along a pixel's ray is seen through with a
// 5 % tolerance and not with 20 %; one on the wall is on its surface and not seen through; one in
// the unusable corner, behind the camera or outside the picture is neither; the skipped view
// decides nothing. A depth scale is the median ratio over the first region with enough pixels.
#include <gtest/gtest.h>

#include <cmath>

#include "camera/camera.h"
#include "camera/trajectory.h"
#include "geometry/depth_alignment.h"
#include "geometry/visibility.h"

namespace ii {
namespace {
namespace visibility_test {

constexpr int kW = 20, kH = 10;

SeenDepth wall_view() {
  SeenDepth s;
  s.camera.K = Intrinsics::from_fov(kW, kH, 60 * M_PI / 180, 2 * std::atan(std::tan(30 * M_PI / 180) * kH / kW));
  s.camera.c2w = look_at({0, 0, 3}, {0, 0, 0}, {0, 1, 0});
  s.depth = torch::full({kH, kW}, 3.0f);
  s.usable = torch::ones({kH, kW}, torch::kBool);
  s.usable.slice(0, 0, 3).slice(1, 0, 4).fill_(false);  // the top-left corner: a mask
  return s;
}

// The world point at camera depth `z` through pixel (x, y)'s centre.
torch::Tensor point_at(const SeenDepth& s, int x, int y, double z) {
  const Rays rays = compute_rays(s.camera);
  const size_t i = 3 * (static_cast<size_t>(y) * kW + x);
  std::vector<double> p(3);
  for (size_t k = 0; k < 3; ++k) p[k] = rays.origin[i + k] + z * rays.dir_unnorm[i + k];
  return torch::tensor(p, torch::kFloat64);
}

TEST(Visibility, SeenThroughAndOnTheSurfaceByTolerance) {
  const SeenDepth s = wall_view();
  const torch::Tensor points = torch::stack({
      point_at(s, 10, 5, 2.7),  // 10 % nearer than the wall
      point_at(s, 10, 5, 3.0),  // on the wall
      point_at(s, 1, 1, 2.7),   // nearer, but where the depth is masked off
      point_at(s, 10, 5, 3.3),  // behind the wall
  });
  const std::vector<SeenDepth> seen = {s};
  EXPECT_TRUE(torch::equal(seen_through(points, seen, 0.05), torch::tensor({true, false, false, false})));
  EXPECT_TRUE(torch::equal(seen_through(points, seen, 0.2), torch::tensor({false, false, false, false})));
  EXPECT_TRUE(torch::equal(seen_through(points, seen, 0.05, /*skip=*/0), torch::tensor({false, false, false, false})));
  EXPECT_TRUE(torch::equal(on_seen_surface(points, s, 0.05), torch::tensor({false, true, false, false})));
  EXPECT_TRUE(torch::equal(on_seen_surface(points, s, 0.15), torch::tensor({true, true, false, true})));
}

TEST(Visibility, NothingBehindTheCameraOrOutsideThePicture) {
  const SeenDepth s = wall_view();
  const torch::Tensor points = torch::stack({torch::tensor({0.0, 0.0, 4.0}, torch::kFloat64),
                                             torch::tensor({50.0, 0.0, 1.0}, torch::kFloat64)});
  EXPECT_TRUE(torch::equal(seen_through(points, {s}, 0.0), torch::tensor({false, false})));
  EXPECT_TRUE(torch::equal(on_seen_surface(points, s, 1.0), torch::tensor({false, false})));
}

TEST(Visibility, MedianDepthRatioOverTheFirstRegionWithEnoughPixels) {
  torch::Tensor measured = torch::full({4, 8}, 2.0f);
  measured.slice(1, 0, 2).fill_(6.0f);  // the first two columns three times farther
  const torch::Tensor predicted = torch::ones({4, 8});
  torch::Tensor left = torch::zeros({4, 8}, torch::kBool), few = left.clone();
  left.slice(1, 0, 2).fill_(true);
  few[0][0] = true;
  const torch::Tensor all = torch::ones({4, 8}, torch::kBool);
  EXPECT_DOUBLE_EQ(median_depth_ratio(measured, predicted, {left, all}, 8), 6.0);
  EXPECT_DOUBLE_EQ(median_depth_ratio(measured, predicted, {few, all}, 8), 2.0);  // too few: the next
  EXPECT_DOUBLE_EQ(median_depth_ratio(measured, predicted, {few}, 8), 1.0);       // none has enough
}

}  // namespace visibility_test
}  // namespace
}  // namespace ii
