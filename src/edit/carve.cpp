#include "edit/carve.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <opencv2/imgproc.hpp>

#include "common/error.h"
#include "common/parallel.h"
#include "data/opencv_image.h"

namespace ii {

namespace {

struct Projected {
  int x, y;
  float z;
  PointRole role;
};

// The points in front of `camera` that land in its picture, with their pixels and depths.
std::vector<Projected> projected(const Camera& camera, const std::vector<Eigen::Vector3d>& points,
                                 const std::vector<PointRole>& roles) {
  const Eigen::Matrix4d w2c = camera.w2c_opencv();
  std::vector<Projected> out;
  for (size_t i = 0; i < points.size(); ++i)
    if (const std::optional<PixelOfPoint> hit = pixel_of_point(camera.K, w2c, points[i]))
      out.push_back({hit->x, hit->y, static_cast<float>(hit->z), roles[i]});
  return out;
}

// GrabCut of `labels` (seeds as they are; `inside`: the propagated mask) over `image`, at most
// options.grabcut_size pixels on a side: the seeds carried to the smaller picture (the object's
// over the rest's), the answer brought back to the picture's size. 255 where the object is.
cv::Mat grab_cut(const cv::Mat& image, const cv::Mat& labels, const cv::Mat& inside, const CarveOptions& options) {
  const int side = std::max(image.cols, image.rows);
  const double s = options.grabcut_size > 0 && side > options.grabcut_size
                       ? static_cast<double>(options.grabcut_size) / side
                       : 1.0;
  cv::Mat small_image = image, small_labels = labels.clone();
  if (s < 1) {
    const cv::Size size(std::max(1, static_cast<int>(std::lround(image.cols * s))),
                        std::max(1, static_cast<int>(std::lround(image.rows * s))));
    cv::resize(image, small_image, size, 0, 0, cv::INTER_AREA);
    cv::resize(labels, small_labels, size, 0, 0, cv::INTER_NEAREST);
    // Probable labels from the nearest pixel; a seed wins over them, the object's over the rest's.
    for (const uint8_t seed : {cv::GC_PR_BGD, cv::GC_BGD, cv::GC_FGD})
      for (int y = 0; y < labels.rows; ++y)
        for (int x = 0; x < labels.cols; ++x) {
          if (labels.at<uint8_t>(y, x) != seed || !inside.at<uint8_t>(y, x)) continue;
          const int sx = std::min(size.width - 1, static_cast<int>(x * s));
          const int sy = std::min(size.height - 1, static_cast<int>(y * s));
          small_labels.at<uint8_t>(sy, sx) = seed;
        }
  }
  cv::Mat background_model, object_model;
  cv::theRNG() = cv::RNG(74);  // its colour models start from k-means: the same masks every run
  cv::grabCut(small_image, small_labels, cv::Rect(), background_model, object_model, options.iterations,
              cv::GC_INIT_WITH_MASK);
  cv::Mat object = ((small_labels == cv::GC_FGD) | (small_labels == cv::GC_PR_FGD));
  if (s < 1) {
    cv::resize(object, object, image.size(), 0, 0, cv::INTER_LINEAR);
    object = object > 127;
  }
  return object;
}

CarvedMask carve_one(const Image& mask, const Image& photo, const Camera& camera,
                     const std::vector<Eigen::Vector3d>& points, const std::vector<PointRole>& roles,
                     const CarveOptions& options) {
  if (photo.width != mask.width || photo.height != mask.height)
    fail("carve: a photo is {}x{} but its mask {}x{}", photo.width, photo.height, mask.width, mask.height);
  CarvedMask out{mask, 0, 0, false};
  const int W = mask.width, H = mask.height;
  cv::Mat inside(H, W, CV_8UC1);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) inside.at<uint8_t>(y, x) = mask.at(y, x) > 0.5f;
  if (cv::countNonZero(inside) == 0) return out;

  // The nearest point of each cell: what the view sees there.
  const std::vector<Projected> seen = projected(camera, points, roles);
  const int cell = std::max(1, options.cell);
  const int cw = (W + cell - 1) / cell, ch = (H + cell - 1) / cell;
  std::vector<float> nearest(static_cast<size_t>(cw) * ch, std::numeric_limits<float>::infinity());
  for (const Projected& p : seen) {
    float& n = nearest[static_cast<size_t>(p.y / cell) * cw + p.x / cell];
    n = std::min(n, p.z);
  }
  // GrabCut's labels: outside the mask the background for certain, inside probably the object;
  // the seen points' pixels as they are.
  cv::Mat labels(H, W, CV_8UC1);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) labels.at<uint8_t>(y, x) = inside.at<uint8_t>(y, x) ? cv::GC_PR_FGD : cv::GC_BGD;
  for (const Projected& p : seen) {
    if (!inside.at<uint8_t>(p.y, p.x)) continue;
    const float n = nearest[static_cast<size_t>(p.y / cell) * cw + p.x / cell];
    if (p.z > n * (1 + options.seen_tolerance)) continue;  // hidden behind what the cell sees
    uint8_t& label = labels.at<uint8_t>(p.y, p.x);
    if (p.role == PointRole::unsure) continue;
    if (p.role == PointRole::object) {
      if (label != cv::GC_BGD) label = cv::GC_FGD, ++out.object_seeds;
    } else if (label != cv::GC_FGD) {
      label = cv::GC_BGD, ++out.other_seeds;
    }
  }
  if (out.object_seeds == 0) return out;
  // Near the object's seeds, a point of the rest may be one the object hides where its own points
  // are missing: there it says "probably not the object" only.
  if (options.near_object > 0) {
    const double near_px = options.near_object * std::max(W, H);
    cv::Mat not_seed = labels != cv::GC_FGD, distance;
    cv::distanceTransform(not_seed, distance, cv::DIST_L2, 3);
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x)
        if (inside.at<uint8_t>(y, x) && labels.at<uint8_t>(y, x) == cv::GC_BGD && distance.at<float>(y, x) < near_px)
          labels.at<uint8_t>(y, x) = cv::GC_PR_BGD;
  }

  // GrabCut over the mask's box and a margin around it (its colour models need some background).
  const cv::Rect box = cv::boundingRect(inside);
  const int margin = std::max(8, std::max(box.width, box.height) / 4);
  const cv::Rect crop = (box + cv::Size(2 * margin, 2 * margin) - cv::Point(margin, margin)) & cv::Rect(0, 0, W, H);
  cv::Mat carved(H, W, CV_8UC1, cv::Scalar(0));
  grab_cut(to_bgr8(photo)(crop), labels(crop), inside(crop), options).copyTo(carved(crop));
  if (options.dilation > 0)
    cv::dilate(carved, carved,
               cv::getStructuringElement(cv::MORPH_ELLIPSE,
                                         cv::Size(2 * options.dilation + 1, 2 * options.dilation + 1)));
  carved &= inside;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) out.mask.at(y, x) = carved.at<uint8_t>(y, x) ? 1.f : 0.f;
  out.carved = true;
  return out;
}

}  // namespace

std::vector<PointRole> point_roles(const PropagatedMasks& lifted, const Image& depth, const Camera& marked,
                                   const std::vector<Eigen::Vector3d>& points, const CarveOptions& options) {
  const std::vector<uint8_t> inside = inside_lifted(lifted, marked, points);
  const Eigen::Matrix4d w2c = marked.w2c_opencv();
  const bool sized = depth.width == marked.K.width && depth.height == marked.K.height;
  std::vector<PointRole> roles(points.size(), PointRole::other);
  for (size_t i = 0; i < points.size(); ++i) {
    if (!inside[i]) continue;
    roles[i] = PointRole::unsure;
    const std::optional<PixelOfPoint> hit = pixel_of_point(marked.K, w2c, points[i]);
    const float d = sized && hit ? depth.at(hit->y, hit->x) : 0.f;
    if (d > 0 && hit->z >= d * (1 - options.surface_in_front) && hit->z <= d * (1 + options.surface_behind))
      roles[i] = PointRole::object;
  }
  return roles;
}

std::vector<CarvedMask> carve_masks(const std::vector<Image>& masks, const PhotoSource& photo,
                                    const std::vector<Camera>& cameras, const std::vector<Eigen::Vector3d>& points,
                                    const std::vector<PointRole>& roles, const CarveOptions& options) {
  if (cameras.size() != masks.size())
    fail("carve: {} masks and {} cameras (one each per view expected)", masks.size(), cameras.size());
  if (roles.size() != points.size()) fail("carve: {} points but {} roles", points.size(), roles.size());
  std::vector<CarvedMask> out(masks.size());
  parallel_dynamic(static_cast<int64_t>(masks.size()), thread_plan().cores, [&](int64_t v) {
    const auto i = static_cast<size_t>(v);
    out[i] = carve_one(masks[i], photo(i), cameras[i], points, roles, options);
  });
  return out;
}

}  // namespace ii
