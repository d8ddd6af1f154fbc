#pragma once
// A line chart of a run's per-step values (e.g. refinement losses) for people to look at.
#include <string>
#include <vector>

#include "io/image.h"

namespace ii {

// `values` per step: each step's value in light grey, their running mean over a window of
// about 2 % of the run in blue, the value axis from the lowest to the highest mean, labelled
// with the first and last mean and the step count. RGB in [0,1]. An empty list gives an empty
// chart with the title.
Image line_chart(const std::vector<double>& values, const std::string& title, int width = 640, int height = 360);

}  // namespace ii
