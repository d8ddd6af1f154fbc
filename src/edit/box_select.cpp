#include "edit/box_select.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "common/error.h"
#include "data/opencv_image.h"

namespace ii {

namespace {

std::string box_text(const ViewBox& box) {
  return fmt::format("{:g},{:g},{:g},{:g}", box[0], box[1], box[2], box[3]);
}

// GrabCut's labels over the crop: outside the box the background for certain, inside probably the
// object; discs of certain object under the clicks and of certain background under the points
// that are not it. `scale` takes photo pixels to the crop's.
cv::Mat seeded_labels(const cv::Size& size, const cv::Rect2d& crop, double scale, const ViewBox& box,
                      const std::vector<Click>& clicks, const std::vector<Click>& not_clicks, int radius) {
  cv::Mat labels(size, CV_8UC1, cv::Scalar(cv::GC_BGD));
  auto at = [&](double x, double y) {
    return cv::Point(static_cast<int>(std::lround((x - crop.x) * scale - 0.5)),
                     static_cast<int>(std::lround((y - crop.y) * scale - 0.5)));
  };
  const cv::Point top_left = at(box[0] + 0.5, box[1] + 0.5), bottom_right = at(box[2] - 0.5, box[3] - 0.5);
  cv::rectangle(labels, top_left, bottom_right, cv::Scalar(cv::GC_PR_FGD), cv::FILLED);
  for (const Click& c : clicks) cv::circle(labels, at(c.x, c.y), radius, cv::Scalar(cv::GC_FGD), cv::FILLED);
  for (const Click& c : not_clicks) cv::circle(labels, at(c.x, c.y), radius, cv::Scalar(cv::GC_BGD), cv::FILLED);
  return labels;
}

}  // namespace

void check_box(const std::string& view, int width, int height, const ViewBox& box, const std::vector<Click>& clicks,
               bool with_network) {
  if (!(box[0] >= 0 && box[1] >= 0 && box[2] <= width && box[3] <= height))
    fail("view {}: the box {} reaches outside its photo ({}x{})", view, box_text(box), width, height);
  if (box[2] - box[0] < 2 || box[3] - box[1] < 2)
    fail("view {}: the box {} is under 2 pixels wide or high: draw it around the object", view, box_text(box));
  const double outside = static_cast<double>(width) * height - (box[2] - box[0]) * (box[3] - box[1]);
  if (!with_network && outside < 0.01 * width * height)
    fail("view {}: the box {} covers the whole photo ({}x{}): without a segmentation network the photo outside the "
         "box is what the object is told apart from; draw the box around the object",
         view, box_text(box), width, height);
  for (const Click& c : clicks)
    if (!(c.x >= box[0] && c.x <= box[2] && c.y >= box[1] && c.y <= box[3]))
      fail("view {}: the click ({}, {}) is outside the box {}: clicks with a box are on the object inside it", view,
           c.x, c.y, box_text(box));
}

Image object_in_box(const Image& photo, const std::string& view, const ViewBox& box, const std::vector<Click>& clicks,
                    const std::vector<Click>& not_clicks, const BoxSelectOptions& options) {
  check_box(view, photo.width, photo.height, box, clicks, false);
  // The crop: the box and a margin of background around it, within the photo.
  const double side = std::max(box[2] - box[0], box[3] - box[1]), margin = options.margin * side;
  const cv::Rect crop = cv::Rect(cv::Point(static_cast<int>(std::floor(std::max(0.0, box[0] - margin))),
                                           static_cast<int>(std::floor(std::max(0.0, box[1] - margin)))),
                                 cv::Point(static_cast<int>(std::ceil(std::min<double>(photo.width, box[2] + margin))),
                                           static_cast<int>(std::ceil(std::min<double>(photo.height, box[3] + margin)))));
  const int crop_side = std::max(crop.width, crop.height);
  const double scale = options.grabcut_size > 0 && crop_side > options.grabcut_size
                           ? static_cast<double>(options.grabcut_size) / crop_side
                           : 1.0;
  const cv::Size size(std::max(1, static_cast<int>(std::lround(crop.width * scale))),
                      std::max(1, static_cast<int>(std::lround(crop.height * scale))));
  cv::Mat image = to_bgr8(photo)(crop);
  if (scale < 1) cv::resize(image, image, size, 0, 0, cv::INTER_AREA);
  const int radius = std::max(1, static_cast<int>(std::lround(options.seed_radius * side * scale)));
  cv::Mat labels = seeded_labels(size, cv::Rect2d(crop), scale, box, clicks, not_clicks, radius);
  cv::Mat background_model, object_model;
  cv::theRNG() = cv::RNG(74);  // its colour models start from k-means: the same mask every run
  try {
    cv::grabCut(image, labels, cv::Rect(), background_model, object_model, options.iterations, cv::GC_INIT_WITH_MASK);
  } catch (const cv::Exception& e) {  // a picture it cannot model (OpenCV's own words)
    fail("view {}: GrabCut failed in the box {}: {}", view, box_text(box), e.err);
  }
  cv::Mat object = (labels == cv::GC_FGD) | (labels == cv::GC_PR_FGD);
  if (scale < 1) {
    cv::resize(object, object, crop.size(), 0, 0, cv::INTER_LINEAR);
    object = object > 127;
  }
  Image mask(photo.width, photo.height, 1);
  int pixels = 0;
  for (int y = 0; y < crop.height; ++y)
    for (int x = 0; x < crop.width; ++x) {
      const int px = crop.x + x, py = crop.y + y;
      // Only inside the box: GrabCut's "certain background" outside it stays so.
      if (!object.at<uint8_t>(y, x) || px + 0.5 < box[0] || px + 0.5 > box[2] || py + 0.5 < box[1] || py + 0.5 > box[3])
        continue;
      mask.at(py, px) = 1.f;
      ++pixels;
    }
  if (pixels == 0) fail("view {}: GrabCut found no object in the box {}", view, box_text(box));
  return mask;
}

}  // namespace ii
