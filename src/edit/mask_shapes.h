#pragma once
// Drawn masks made whole (the edit folder's own; OpenCV in the interface).
#include <opencv2/imgproc.hpp>

#include "io/image.h"

namespace ii {

// `canvas` (8-bit, non-zero = drawn): small gaps between the strokes closed, enclosed holes
// filled, `dilation` pixels added around; values 0/1.
Image finish_mask(cv::Mat& canvas, int dilation);

}  // namespace ii
