#include "data/undistort.h"

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "common/error.h"

namespace ii {

namespace {

Image remap_undistorted(const Image& image, const Intrinsics& K, const Distortion& d, int interpolation) {
  if (image.empty() || image.width != K.width || image.height != K.height)
    fail("undistortion: image is {}x{} but the camera is {}x{}", image.width, image.height, K.width, K.height);
  if (image.channels < 1 || image.channels > 4) fail("undistortion: {} channels are not supported", image.channels);
  if (!d.any()) return image;
  // OpenCV's pixel centres sit at integers, ours at +0.5: shift the principal point.
  const cv::Matx33d cam(K.fx, 0, K.cx - 0.5, 0, K.fy, K.cy - 0.5, 0, 0, 1);
  const std::vector<double> coeffs(d.coeffs.begin(), d.coeffs.end());
  Image out(image.width, image.height, image.channels);
  try {
    // Same K in and out: the undistorted image fits the plain pinhole camera of the view.
    cv::Mat map1, map2;
    cv::initUndistortRectifyMap(cam, coeffs, cv::noArray(), cam, cv::Size(K.width, K.height), CV_32FC1, map1, map2);
    const cv::Mat src(image.height, image.width, CV_32FC(image.channels), const_cast<float*>(image.pixels.data()));
    cv::Mat dst(out.height, out.width, CV_32FC(out.channels), out.pixels.data());
    // Replicated borders: corners that map outside the source repeat the edge instead of
    // turning black (which would read as content to the network).
    cv::remap(src, dst, map1, map2, interpolation, cv::BORDER_REPLICATE);
  } catch (const cv::Exception& e) {
    fail("undistortion failed: {}", e.what());
  }
  return out;
}

}  // namespace

Image undistort_image(const Image& image, const Intrinsics& K, const Distortion& distortion) {
  return remap_undistorted(image, K, distortion, cv::INTER_LINEAR);
}

Image undistort_mask(const Image& mask, const Intrinsics& K, const Distortion& distortion) {
  // Nearest neighbour keeps a binary mask binary.
  return remap_undistorted(mask, K, distortion, cv::INTER_NEAREST);
}

}  // namespace ii
