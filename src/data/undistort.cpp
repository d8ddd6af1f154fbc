#include "data/undistort.h"

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "common/error.h"

namespace ii {

namespace {

Image remap_undistorted(const Image& image, const Intrinsics& K, const Distortion& d, int interpolation) {
  if (image.width != K.width || image.height != K.height)
    fail("undistortion: image is {}x{} but the camera is {}x{}", image.width, image.height, K.width, K.height);
  // OpenCV's pixel grid has centres at integers; ours at +0.5, hence the half-pixel shift.
  const cv::Matx33d cam(K.fx, 0, K.cx - 0.5, 0, K.fy, K.cy - 0.5, 0, 0, 1);
  const std::vector<double> coeffs(d.coeffs.begin(), d.coeffs.end());
  cv::Mat map1, map2;
  cv::initUndistortRectifyMap(cam, coeffs, cv::noArray(), cam, cv::Size(K.width, K.height), CV_32FC1, map1, map2);
  const cv::Mat src(image.height, image.width, CV_32FC(image.channels), const_cast<float*>(image.pixels.data()));
  Image out(image.width, image.height, image.channels);
  cv::Mat dst(out.height, out.width, CV_32FC(out.channels), out.pixels.data());
  cv::remap(src, dst, map1, map2, interpolation, cv::BORDER_REPLICATE);
  return out;
}

}  // namespace

Image undistort_image(const Image& image, const Intrinsics& K, const Distortion& distortion) {
  return remap_undistorted(image, K, distortion, cv::INTER_LINEAR);
}

Image undistort_mask(const Image& mask, const Intrinsics& K, const Distortion& distortion) {
  return remap_undistorted(mask, K, distortion, cv::INTER_NEAREST);
}

}  // namespace ii
