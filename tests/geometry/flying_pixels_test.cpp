// Flying pixels: a depth map's pixels that straddle an edge (a mean of both sides' depths) are
// found, moved to the far side's depth and given its colour; a steep plane, unknown pixels and
// the picture's border are left alone; bad settings are named.
#include <gtest/gtest.h>

#include <string>

#include "common/error.h"
#include "geometry/flying_pixels.h"

namespace ii {
namespace {
// A namespace of its own: the folder's test files are compiled together (CMake's unity build).
namespace flying_pixels_test {

using torch::indexing::Slice;

// A wall at depth 2 behind a box at depth 1 in columns 0-9 of a 12 x 20 map; column 10 is
// `mixed` (a pixel the edge crosses).
torch::Tensor box_before_wall(float mixed) {
  torch::Tensor d = torch::full({12, 20}, 2.0f);
  d.index_put_({Slice(), Slice(0, 10)}, 1.0f);
  d.index_put_({Slice(), 10}, mixed);
  return d;
}

TEST(FlyingPixels, AMixedColumnGoesToTheFarSideWithItsColour) {
  const torch::Tensor depth = box_before_wall(1.4f);
  const torch::Tensor flying = flying_pixels(depth, FlyingPixelOptions());
  torch::Tensor expected = torch::zeros({12, 20}, torch::kBool);
  expected.index_put_({Slice(), 10}, true);
  EXPECT_TRUE(torch::equal(flying, expected));

  const FarSide far = flying_pixels_to_far_side(depth, FlyingPixelOptions());
  EXPECT_TRUE(torch::equal(far.moved, expected));
  EXPECT_TRUE(torch::equal(far.depth, box_before_wall(2.0f)));
  // Each moved pixel takes a wall pixel's colour; the others keep their own.
  torch::Tensor colour = torch::zeros({3, 12, 20});
  colour.index_put_({0, Slice(), Slice(0, 10)}, 1.0f);      // the box red
  colour.index_put_({2, Slice(), Slice(11, 20)}, 1.0f);   // the wall blue
  colour.index_put_({Slice(), Slice(), 10}, 0.5f);          // the edge a mix
  const torch::Tensor moved_colour = far_side_colours(colour, far);
  EXPECT_TRUE(torch::equal(moved_colour.index({Slice(), Slice(), 10}),
                           colour.index({Slice(), Slice(), 11})));
  const torch::Tensor kept = expected.logical_not();
  EXPECT_TRUE(torch::equal(moved_colour.index({Slice(), kept}), colour.index({Slice(), kept})));
}

TEST(FlyingPixels, EdgesWithoutAMixedPixelAndSteepPlanesStay) {
  // A clean edge, and a pixel within 3 % of the box (its own side).
  EXPECT_FALSE(flying_pixels(box_before_wall(2.0f), FlyingPixelOptions()).any().item<bool>());
  EXPECT_FALSE(flying_pixels(box_before_wall(1.02f), FlyingPixelOptions()).any().item<bool>());
  // A floor seen at a grazing angle: its inverse depth affine in the pixel, 12 % of it a column.
  const torch::Tensor x = torch::arange(20, torch::kFloat32).view({1, 20}).expand({12, 20});
  const torch::Tensor steep = (0.5 + 0.06 * (19 - x)).reciprocal().contiguous();
  EXPECT_GT((steep.index({0, 19}) / steep.index({0, 17})).item<float>(), 1.2f);  // an "edge" over 2 pixels
  EXPECT_FALSE(flying_pixels(steep, FlyingPixelOptions()).any().item<bool>());
  // Unknown pixels (0, infinite) are no side of an edge.
  torch::Tensor holes = box_before_wall(1.4f);
  holes.index_put_({Slice(), 11}, 0.0f);
  holes.index_put_({Slice(), 9}, std::numeric_limits<float>::infinity());
  EXPECT_FALSE(flying_pixels(holes, FlyingPixelOptions()).any().item<bool>());
}

TEST(FlyingPixels, NoSureSideWithinReachLeavesTheDepthUnknown) {
  // A ramp of mixed pixels wider than the reach: its middle has no sure pixel in reach.
  torch::Tensor d = torch::full({9, 30}, 4.0f);
  d.index_put_({Slice(), Slice(0, 10)}, 1.0f);
  for (int64_t c = 10; c < 20; ++c) d.index_put_({Slice(), c}, 1.0f + 0.3f * static_cast<float>(c - 9));
  FlyingPixelOptions options;
  options.reach = 2;
  const FarSide far = flying_pixels_to_far_side(d, options);
  const torch::Tensor flying = flying_pixels(d, options);
  EXPECT_GT(flying.sum().item<int64_t>(), 0);
  EXPECT_TRUE(torch::equal(far.moved.logical_or(far.depth.eq(0)), flying.logical_or(far.moved)));
  EXPECT_TRUE(far.depth.index({flying.logical_not()}).equal(d.index({flying.logical_not()})));
  EXPECT_TRUE(far.depth.index({flying.logical_and(far.moved.logical_not())}).eq(0).all().item<bool>());
}

TEST(FlyingPixels, BadSettingsAndSizesAreNamed) {
  FlyingPixelOptions bad;
  bad.reach = 0;
  try {
    flying_pixels(torch::ones({4, 4}), bad);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              "flying pixels: jump must be > 0, apart and bend >= 0, reach 1-64 (got 0.1, 0.03, 0.02, 0)");
  }
  try {
    flying_pixels(torch::ones({4}), FlyingPixelOptions());
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "flying pixels: the depth map must be (H, W), got 1 dimensions");
  }
  const FarSide far = flying_pixels_to_far_side(torch::ones({4, 5}), FlyingPixelOptions());
  try {
    far_side_colours(torch::ones({3, 5, 4}), far);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "flying pixels: the colours must be (C, 4, 5)");
  }
}

}  // namespace flying_pixels_test
}  // namespace
}  // namespace ii
