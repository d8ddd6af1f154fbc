#include "data/opencv_image.h"

#include <algorithm>
#include <cmath>

namespace ii {

cv::Mat to_bgr8(const Image& image) {
  cv::Mat out(image.height, image.width, CV_8UC3);
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x)
      for (int c = 0; c < 3; ++c)
        out.at<cv::Vec3b>(y, x)[2 - c] = static_cast<uint8_t>(
            std::lround(std::clamp(image.at(y, x, image.channels == 1 ? 0 : c), 0.f, 1.f) * 255.f));
  return out;
}

Image from_bgr8(const cv::Mat& bgr) {
  Image out(bgr.cols, bgr.rows, 3);
  for (int y = 0; y < bgr.rows; ++y)
    for (int x = 0; x < bgr.cols; ++x)
      for (int c = 0; c < 3; ++c) out.at(y, x, c) = bgr.at<cv::Vec3b>(y, x)[2 - c] / 255.f;
  return out;
}

}  // namespace ii
