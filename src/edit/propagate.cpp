#include "edit/propagate.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#include "common/error.h"
#include "common/parallel.h"
#include "edit/mask_shapes.h"

namespace ii {

namespace {

bool known_depth(float z) { return std::isfinite(z) && z > 0; }

cv::Mat binary_mask(const Image& image) {
  cv::Mat out(image.height, image.width, CV_8UC1);
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x) out.at<uint8_t>(y, x) = image.at(y, x) > 0.5f ? 1 : 0;
  return out;
}

double quantile(std::vector<double> values, double q) {
  const auto k = static_cast<std::ptrdiff_t>(std::lround(q * static_cast<double>(values.size() - 1)));
  std::nth_element(values.begin(), values.begin() + k, values.end());
  return values[static_cast<size_t>(k)];
}

// Liang-Barsky: clips the 2D segment p0-p1 to the box [lo, hi]; false when nothing is left.
bool clip_to_box(Eigen::Vector2d& p0, Eigen::Vector2d& p1, const Eigen::Vector2d& lo, const Eigen::Vector2d& hi) {
  double t0 = 0, t1 = 1;
  const Eigen::Vector2d d = p1 - p0;
  for (int axis = 0; axis < 2; ++axis) {
    for (const double sign : {-1.0, 1.0}) {
      const double p = sign * d[axis];
      const double q = sign < 0 ? p0[axis] - lo[axis] : hi[axis] - p0[axis];
      if (p == 0) {
        if (q < 0) return false;
        continue;
      }
      const double r = q / p;
      if (p < 0) t0 = std::max(t0, r);
      else t1 = std::min(t1, r);
      if (t0 > t1) return false;
    }
  }
  const Eigen::Vector2d start = p0 + t0 * d;
  p1 = p0 + t1 * d;
  p0 = start;
  return true;
}

// Draws the image of the world segment a-b in a camera (world-to-camera in OpenCV axes):
// the part in front of the camera, clipped to the image.
void draw_segment(cv::Mat& canvas, const Intrinsics& K, const Eigen::Matrix4d& w2c, const Eigen::Vector3d& a,
                  const Eigen::Vector3d& b, double min_z) {
  Eigen::Vector3d ca = w2c.topLeftCorner<3, 3>() * a + w2c.topRightCorner<3, 1>();
  Eigen::Vector3d cb = w2c.topLeftCorner<3, 3>() * b + w2c.topRightCorner<3, 1>();
  if (ca.z() < min_z && cb.z() < min_z) return;
  if (ca.z() < min_z) ca = cb + (ca - cb) * ((cb.z() - min_z) / (cb.z() - ca.z()));
  if (cb.z() < min_z) cb = ca + (cb - ca) * ((ca.z() - min_z) / (ca.z() - cb.z()));
  // Pixel indices (centres at +0.5 in continuous coordinates).
  Eigen::Vector2d pa(K.fx * ca.x() / ca.z() + K.cx - 0.5, K.fy * ca.y() / ca.z() + K.cy - 0.5);
  Eigen::Vector2d pb(K.fx * cb.x() / cb.z() + K.cx - 0.5, K.fy * cb.y() / cb.z() + K.cy - 0.5);
  if (!clip_to_box(pa, pb, Eigen::Vector2d(-1, -1), Eigen::Vector2d(K.width, K.height))) return;
  cv::line(canvas, cv::Point(static_cast<int>(std::lround(pa.x())), static_cast<int>(std::lround(pa.y()))),
           cv::Point(static_cast<int>(std::lround(pb.x())), static_cast<int>(std::lround(pb.y()))), cv::Scalar(1), 1,
           cv::LINE_8);
}

}  // namespace

std::string edit_mode_name(EditMode mode) { return mode == EditMode::Insert ? "insert" : "remove"; }

EditMode parse_edit_mode(const std::string& name) {
  if (name == "remove") return EditMode::Remove;
  if (name == "insert") return EditMode::Insert;
  fail("unknown edit mode '{}' (remove or insert)", name);
}

PropagatedMasks propagate_mask(const Image& region, const Image& depth, const Camera& camera,
                               const std::vector<Camera>& targets, const PropagationOptions& options) {
  const int W = camera.K.width, H = camera.K.height;
  if (region.width != W || region.height != H || region.channels != 1)
    fail("region mask: {}x{} with {} channels, the view is {}x{} (one channel expected)", region.width, region.height,
         region.channels, W, H);
  if (depth.width != W || depth.height != H || depth.channels != 1)
    fail("depth map: {}x{} with {} channels, the view is {}x{} (one channel expected)", depth.width, depth.height,
         depth.channels, W, H);
  if (options.extent && !(*options.extent > 0 && std::isfinite(*options.extent)))
    fail("the insertion extent must be a positive number of scene units, got {}", *options.extent);
  if (!(options.depth_margin >= 0 && options.depth_margin < 1))
    fail("the depth margin must be in [0, 1), got {}", options.depth_margin);
  if (!(options.max_depth_ratio >= 0)) fail("the depth ratio must be 0 or positive, got {}", options.max_depth_ratio);

  const cv::Mat marked = binary_mask(region);
  if (cv::countNonZero(marked) == 0) fail("the region mask is empty: mark the region with white (> 0.5) pixels");
  cv::Mat labels;
  const int count = cv::connectedComponents(marked, labels, 8, CV_32S);

  // Depth with unknown = +inf, and its 7x7 minimum: depth maps blur object edges towards the
  // background, and a segment that starts too deep misses the object's silhouette elsewhere.
  cv::Mat z(H, W, CV_32FC1);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const float d = depth.at(y, x);
      z.at<float>(y, x) = known_depth(d) ? d : std::numeric_limits<float>::infinity();
    }
  cv::Mat z_near;
  cv::erode(z, z_near, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(7, 7)), cv::Point(-1, -1), 1,
            cv::BORDER_REPLICATE);

  const Eigen::Matrix4d c2w = opengl_to_opencv(camera.c2w);
  auto point_at = [&](int x, int y, double t) -> Eigen::Vector3d {
    const Eigen::Vector3d local(t * (x + 0.5 - camera.K.cx) / camera.K.fx, t * (y + 0.5 - camera.K.cy) / camera.K.fy, t);
    return c2w.topLeftCorner<3, 3>() * local + c2w.topRightCorner<3, 1>();
  };

  const double m = options.depth_margin;
  PropagatedMasks out;
  out.near = Image(W, H, 1);
  out.far = Image(W, H, 1);
  // Every region pixel's world segment, drawn afterwards into each view (the views side by side).
  struct Segment {
    Eigen::Vector3d a, b;
    double min_z;
  };
  std::vector<Segment> segments;
  for (int k = 1; k < count; ++k) {
    const cv::Mat component = labels == k;
    LiftedRegion lifted;
    lifted.pixels = cv::countNonZero(component);
    const int r = std::max(5, static_cast<int>(std::lround(0.1 * std::sqrt(static_cast<double>(lifted.pixels)))));
    cv::Mat ring;
    cv::dilate(component, ring, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * r + 1, 2 * r + 1)));
    ring &= marked == 0;

    std::vector<double> inside, around;
    const cv::Rect box = cv::boundingRect(component);
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        const float d = depth.at(y, x);
        if (component.at<uint8_t>(y, x)) {
          if (known_depth(d)) inside.push_back(d);
        } else if (ring.at<uint8_t>(y, x) && known_depth(d)) {
          around.push_back(d);
        }
      }
    lifted.depth_inside = static_cast<int>(inside.size());
    lifted.depth_ring = static_cast<int>(around.size());
    if (inside.empty() && around.empty())
      fail("region {} of {} ({} pixels) has no known depth inside it or around it", k, count - 1, lifted.pixels);

    // Remove: nearest object surface through the farthest background. Insert: the background
    // surface, and the new object in front of it.
    double background = 0, extent = 0;
    if (options.mode == EditMode::Remove) {
      lifted.near = inside.empty() ? 0.5 * quantile(around, 0.02) : quantile(inside, 0.02) * (1 - m);
      const double far_inside = inside.empty() ? 0 : quantile(inside, 0.98);
      lifted.far = around.empty() ? 1.5 * far_inside : std::max(far_inside, quantile(around, 0.98));
      lifted.far *= 1 + m;
      if (options.max_depth_ratio > 0 && !inside.empty()) {
        // The region's width in 3D at the object's typical depth (the outline's pixels often
        // carry the background's depth: the median, not the farthest). Objects standing in a
        // scene are about as deep as they are wide, whatever their height.
        const double typical = quantile(inside, 0.5), deep = quantile(inside, 0.9);
        const double extent3d = box.width / camera.K.fx * typical;
        lifted.far = std::min(lifted.far, std::max(deep, lifted.near + options.max_depth_ratio * extent3d) * (1 + m));
      }
    } else {
      background = quantile(inside.empty() ? around : inside, 0.5);
      extent = options.extent.value_or(box.width * background / camera.K.fx);
      lifted.near = std::max(1e-3 * background, quantile(inside.empty() ? around : inside, 0.02) * (1 - m) - extent);
      lifted.far = quantile(inside.empty() ? around : inside, 0.98) * (1 + m);
    }
    const double min_z = 1e-4 * lifted.far;

    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        if (!component.at<uint8_t>(y, x)) continue;
        double t0 = lifted.near, t1 = lifted.far;
        const float d = depth.at(y, x);
        if (!options.pixel_depth) {
          // the region's whole range
        } else if (options.mode == EditMode::Remove) {
          const float nearest = z_near.at<float>(y, x);
          if (std::isfinite(nearest)) t0 = std::clamp(nearest * (1 - m), lifted.near, lifted.far);
        } else if (known_depth(d)) {
          t1 = d * (1 + m);
          t0 = std::max(1e-3 * d, d * (1 - m) - extent);
        }
        segments.push_back({point_at(x, y, t0), point_at(x, y, t1), min_z});
        out.near.at(y, x) = static_cast<float>(t0);
        out.far.at(y, x) = static_cast<float>(t1);
      }
    out.regions.push_back(lifted);
  }
  out.masks.resize(targets.size());
  parallel_dynamic(static_cast<int64_t>(targets.size()), thread_plan().cores, [&](int64_t v) {
    const Camera& target = targets[static_cast<size_t>(v)];
    const Eigen::Matrix4d w2c = target.w2c_opencv();
    cv::Mat canvas(target.K.height, target.K.width, CV_8UC1, cv::Scalar(0));
    for (const Segment& s : segments) draw_segment(canvas, target.K, w2c, s.a, s.b, s.min_z);
    const int automatic = std::max(2, static_cast<int>(std::lround(0.01 * std::max(canvas.cols, canvas.rows))));
    out.masks[static_cast<size_t>(v)] = finish_mask(canvas, options.dilation >= 0 ? options.dilation : automatic);
  });
  return out;
}

std::vector<uint8_t> inside_lifted(const PropagatedMasks& lifted, const Camera& camera,
                                   const std::vector<Eigen::Vector3d>& points) {
  const Eigen::Matrix4d w2c = camera.w2c_opencv();
  std::vector<uint8_t> inside(points.size(), 0);
  if (lifted.near.width != camera.K.width || lifted.near.height != camera.K.height) return inside;
  for (size_t i = 0; i < points.size(); ++i) {
    const std::optional<PixelOfPoint> hit = pixel_of_point(camera.K, w2c, points[i]);
    if (!hit) continue;
    const float near = lifted.near.at(hit->y, hit->x), far = lifted.far.at(hit->y, hit->x);
    inside[i] = far > 0 && hit->z >= near && hit->z <= far;
  }
  return inside;
}

MaskAgreement mask_agreement(const Image& propagated, const Image& truth) {
  if (propagated.width != truth.width || propagated.height != truth.height || propagated.channels != 1 ||
      truth.channels != 1)
    fail("masks differ in size: {}x{}x{} and {}x{}x{} (one channel each expected)", propagated.width,
         propagated.height, propagated.channels, truth.width, truth.height, truth.channels);
  size_t both = 0, true_count = 0, propagated_count = 0;
  for (size_t i = 0; i < truth.pixels.size(); ++i) {
    const bool t = truth.pixels[i] > 0.5f, p = propagated.pixels[i] > 0.5f;
    both += t && p;
    true_count += t;
    propagated_count += p;
  }
  MaskAgreement a;
  if (true_count) a.recall = static_cast<double>(both) / static_cast<double>(true_count);
  if (propagated_count) a.precision = static_cast<double>(both) / static_cast<double>(propagated_count);
  return a;
}

}  // namespace ii
