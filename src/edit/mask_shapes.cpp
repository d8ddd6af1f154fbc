#include "edit/mask_shapes.h"

namespace ii {

Image finish_mask(cv::Mat& canvas, int dilation) {
  const cv::Mat close_kernel = cv::getStructuringElement(cv::MORPH_RECT, cv::Size(5, 5));
  cv::morphologyEx(canvas, canvas, cv::MORPH_CLOSE, close_kernel, cv::Point(-1, -1), 1, cv::BORDER_CONSTANT,
                   cv::Scalar(0));
  cv::Mat padded;
  cv::copyMakeBorder(canvas, padded, 1, 1, 1, 1, cv::BORDER_CONSTANT, cv::Scalar(0));
  cv::floodFill(padded, cv::Point(0, 0), cv::Scalar(2));  // the outside
  cv::Mat filled = padded(cv::Rect(1, 1, canvas.cols, canvas.rows)) != 2;
  if (dilation > 0) {
    const cv::Mat kernel = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * dilation + 1, 2 * dilation + 1));
    cv::dilate(filled, filled, kernel, cv::Point(-1, -1), 1, cv::BORDER_CONSTANT, cv::Scalar(0));
  }
  Image out(canvas.cols, canvas.rows, 1);
  for (int y = 0; y < canvas.rows; ++y)
    for (int x = 0; x < canvas.cols; ++x) out.at(y, x) = filled.at<uint8_t>(y, x) ? 1.f : 0.f;
  return out;
}

}  // namespace ii
