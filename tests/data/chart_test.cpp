// The loss chart: a falling series is drawn from the top left to the bottom right.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "data/chart.h"

namespace ii {
namespace {

// Rows of column x where the chart is blue (the running mean's line).
std::vector<int> blue_rows(const Image& chart, int x) {
  std::vector<int> rows;
  for (int y = 0; y < chart.height; ++y)
    if (chart.at(y, x, 2) > 0.6f && chart.at(y, x, 0) < 0.4f) rows.push_back(y);
  return rows;
}

TEST(LineChart, AFallingSeriesGoesFromTopLeftToBottomRight) {
  std::vector<double> values;
  for (int i = 0; i < 500; ++i) values.push_back(1.0 / (1 + 0.02 * i));
  const Image chart = line_chart(values, "loss", 640, 360);
  ASSERT_EQ(chart.width, 640);
  ASSERT_EQ(chart.height, 360);
  ASSERT_EQ(chart.channels, 3);
  EXPECT_EQ(chart.at(2, 630, 0), 1.f);  // white background
  const std::vector<int> left = blue_rows(chart, 75), right = blue_rows(chart, 615);
  ASSERT_FALSE(left.empty());
  ASSERT_FALSE(right.empty());
  EXPECT_LT(left.front(), 360 / 3);
  EXPECT_GT(right.back(), 2 * 360 / 3);
}

TEST(LineChart, EmptyOrNonFiniteSeriesDrawNoLine) {
  for (const std::vector<double>& values : {std::vector<double>{}, std::vector<double>{1.0, std::nan("")}}) {
    const Image chart = line_chart(values, "loss", 320, 200);
    for (int x = 0; x < 320; x += 7) EXPECT_TRUE(blue_rows(chart, x).empty()) << x;
  }
}

}  // namespace
}  // namespace ii
