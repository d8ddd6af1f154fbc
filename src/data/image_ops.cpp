#include "data/image_ops.h"

#include <opencv2/imgproc.hpp>

#include "common/error.h"

namespace ii {

namespace {

Image resize_with(const Image& image, int width, int height, int interpolation) {
  if (width <= 0 || height <= 0) fail("cannot resize an image to {}x{}", width, height);
  if (image.empty()) fail("cannot resize an empty image");
  if (width == image.width && height == image.height) return image;
  const cv::Mat src(image.height, image.width, CV_32FC(image.channels),
                    const_cast<float*>(image.pixels.data()));
  Image out(width, height, image.channels);
  cv::Mat dst(height, width, CV_32FC(image.channels), out.pixels.data());
  cv::resize(src, dst, dst.size(), 0, 0, interpolation);
  return out;
}

}  // namespace

Image resize_area(const Image& image, int width, int height) {
  return resize_with(image, width, height, cv::INTER_AREA);
}

Image resize_nearest(const Image& image, int width, int height) {
  return resize_with(image, width, height, cv::INTER_NEAREST);
}

Image resize_cubic(const Image& image, int width, int height) {
  return resize_with(image, width, height, cv::INTER_CUBIC);
}

Image crop(const Image& image, int x0, int y0, int width, int height) {
  if (x0 < 0 || y0 < 0 || width <= 0 || height <= 0 || x0 + width > image.width ||
      y0 + height > image.height)
    fail("crop {}x{} at ({}, {}) is outside the {}x{} image", width, height, x0, y0, image.width,
         image.height);
  Image out(width, height, image.channels);
  const size_t row = static_cast<size_t>(width) * image.channels;
  for (int y = 0; y < height; ++y)
    std::copy_n(&image.pixels[(static_cast<size_t>(y0 + y) * image.width + x0) * image.channels], row,
                &out.pixels[static_cast<size_t>(y) * row]);
  return out;
}

Image inferno_colours(const std::vector<uint8_t>& levels, int width, int height) {
  if (levels.size() != static_cast<size_t>(width) * height)
    fail("inferno_colours: {} levels for a {}x{} image", levels.size(), width, height);
  const cv::Mat grey(height, width, CV_8UC1, const_cast<uint8_t*>(levels.data()));
  cv::Mat bgr;
  cv::applyColorMap(grey, bgr, cv::COLORMAP_INFERNO);
  Image out(width, height, 3);
  for (size_t i = 0; i < levels.size(); ++i)
    for (int c = 0; c < 3; ++c) out.pixels[i * 3 + c] = bgr.data[i * 3 + (2 - c)] / 255.f;
  return out;
}

}  // namespace ii
