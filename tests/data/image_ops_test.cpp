// Image operations beyond resizing (which preprocess_test covers): the INFERNO colour map.
#include <gtest/gtest.h>

#include "data/image_ops.h"
#include "test_support.h"

namespace ii {
namespace {

TEST(ImageOps, InfernoRunsFromBlackThroughRedToYellow) {
  const Image c = inferno_colours({0, 128, 255, 255, 0, 0}, 3, 2);
  ASSERT_EQ(c.width, 3);
  ASSERT_EQ(c.height, 2);
  ASSERT_EQ(c.channels, 3);
  // Level 0: near black; 128: reddish (red above blue above green); 255: pale yellow.
  EXPECT_LT(c.at(0, 0, 0) + c.at(0, 0, 1) + c.at(0, 0, 2), 0.1f);
  EXPECT_GT(c.at(0, 1, 0), c.at(0, 1, 2));
  EXPECT_GT(c.at(0, 1, 2), c.at(0, 1, 1));
  EXPECT_GT(c.at(0, 2, 0), 0.95f);
  EXPECT_GT(c.at(0, 2, 1), 0.95f);
  EXPECT_LT(c.at(0, 2, 2), 0.7f);
  EXPECT_EQ(c.at(1, 0, 1), c.at(0, 2, 1));  // same level, same colour
  EXPECT_EQ(test::error_message([] { inferno_colours({1, 2, 3}, 2, 2); }), "inferno_colours: 3 levels for a 2x2 image");
}

}  // namespace
}  // namespace ii
