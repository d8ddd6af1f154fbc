#pragma once
// Images to and from OpenCV's 8-bit BGR matrices, for the OpenCV calls that draw on photos or
// decide by their colours (GrabCut, contours). OpenCV in the interface.
#include <opencv2/core.hpp>

#include "io/image.h"

namespace ii {

// RGB in [0, 1] (a one-channel image as grey) -> 8-bit BGR, rounded and clamped.
cv::Mat to_bgr8(const Image& image);
// 8-bit BGR -> RGB in [0, 1].
Image from_bgr8(const cv::Mat& bgr);

}  // namespace ii
