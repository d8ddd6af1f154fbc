// The window maximum with its index: LibTorch's max_pool2d_with_indices answers exactly, ties
// (many equal values, as the geometry's zeros) included, at the borders and for windows wider
// than the picture.
#include <gtest/gtest.h>

#include "common/error.h"
#include "tensor/window_max.h"

namespace ii {
namespace {

TEST(WindowMax, IsLibTorchsPoolingExactlyTiesIncluded) {
  torch::manual_seed(3);
  for (const auto& [h, w] : std::vector<std::pair<int64_t, int64_t>>{{37, 53}, {8, 5}, {1, 20}, {64, 96}})
    for (int64_t radius : {0, 1, 2, 8, 12}) {
      // Values in steps of a quarter, most of them zero: ties everywhere.
      torch::Tensor x = (torch::randint(0, 9, {h, w}).to(torch::kFloat32) * 0.25f);
      x = torch::where(torch::rand({h, w}).lt(0.6f), torch::zeros_like(x), x);
      const WindowMax ours = window_max_with_index(x, radius);
      const auto [value, index] = torch::max_pool2d_with_indices(x.view({1, 1, h, w}), {2 * radius + 1, 2 * radius + 1},
                                                                 {1, 1}, {radius, radius});
      ASSERT_TRUE(torch::equal(ours.value, value.view({h, w}))) << h << "x" << w << " radius " << radius;
      ASSERT_TRUE(torch::equal(ours.index, index.view({h, w}))) << h << "x" << w << " radius " << radius;
    }
}

TEST(WindowMax, OtherDtypesAreLibTorchsAndBadShapesAreRefused) {
  torch::manual_seed(4);
  const torch::Tensor x = torch::rand({6, 7}).to(torch::kFloat64);
  const WindowMax ours = window_max_with_index(x, 2);
  EXPECT_EQ(ours.value.scalar_type(), torch::kFloat64);
  EXPECT_TRUE(torch::equal(ours.value, std::get<0>(torch::max_pool2d_with_indices(x.view({1, 1, 6, 7}), {5, 5}, {1, 1}, {2, 2})).view({6, 7})));
  EXPECT_THROW(window_max_with_index(torch::rand({2, 6, 7}), 1), Error);
  EXPECT_THROW(window_max_with_index(x, -1), Error);
}

}  // namespace
}  // namespace ii
