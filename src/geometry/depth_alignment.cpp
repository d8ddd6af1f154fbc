#include "geometry/depth_alignment.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <opencv2/imgproc.hpp>

#include "common/parallel.h"
#include "common/torch.h"
#include "data/masks.h"

namespace ii {

namespace {

struct PointSample {
  int x = 0, y = 0;
  double z = 0, predicted = 0;  // the point's camera z; the network's depth at its pixel
};

// The points that project inside the view where `use` is set, with the predicted depth there.
std::vector<PointSample> point_samples(const float* depth, const Image& use, const Camera& camera,
                                       const std::vector<Eigen::Vector3d>& points) {
  const int w = camera.K.width, h = camera.K.height;
  const Eigen::Matrix4d w2c = camera.w2c_opencv();
  std::vector<PointSample> out;
  for (const Eigen::Vector3d& p : points) {
    const Eigen::Vector3d c = w2c.block<3, 3>(0, 0) * p + w2c.block<3, 1>(0, 3);
    if (!(c.z() > 0)) continue;
    const double u = camera.K.fx * c.x() / c.z() + camera.K.cx, v = camera.K.fy * c.y() / c.z() + camera.K.cy;
    if (!(u >= 0 && v >= 0 && u < w && v < h)) continue;
    const int x = static_cast<int>(u), y = static_cast<int>(v);
    if (use.at(y, x) < 0.5f) continue;
    // Bilinear between pixel centres: the depth across a pixel of a slanted surface varies.
    const double fx = std::clamp(u - 0.5, 0.0, w - 1.0), fy = std::clamp(v - 0.5, 0.0, h - 1.0);
    const int x0 = std::min(static_cast<int>(fx), std::max(0, w - 2)),
              y0 = std::min(static_cast<int>(fy), std::max(0, h - 2));
    const int x1 = std::min(x0 + 1, w - 1), y1 = std::min(y0 + 1, h - 1);
    const double ax = fx - x0, ay = fy - y0;
    auto at = [&](int yy, int xx) { return static_cast<double>(depth[static_cast<size_t>(yy) * w + xx]); };
    const double predicted =
        (1 - ay) * ((1 - ax) * at(y0, x0) + ax * at(y0, x1)) + ay * ((1 - ax) * at(y1, x0) + ax * at(y1, x1));
    if (predicted > 0 && std::isfinite(predicted)) out.push_back({x, y, c.z(), predicted});
  }
  return out;
}

double median_ratio(const std::vector<PointSample>& samples) {
  if (samples.empty()) return 1.0;
  std::vector<double> ratios;
  ratios.reserve(samples.size());
  for (const PointSample& s : samples) ratios.push_back(s.z / s.predicted);
  const auto mid = ratios.begin() + static_cast<std::ptrdiff_t>(ratios.size() / 2);
  std::nth_element(ratios.begin(), mid, ratios.end());
  return *mid;
}

// The points that are not hidden: a point farther than `front` x the nearest within a spacing of
// it was seen by another view past a surface this one sees (a synthetic room's depth maps are
// every view's; photos' points are seen by several).
std::vector<PointSample> front_points(const std::vector<PointSample>& samples, double spacing, double front, int w,
                                      int h) {
  const int cell = std::max(1, static_cast<int>(std::lround(spacing)));
  const int gw = (w + cell - 1) / cell, gh = (h + cell - 1) / cell;
  std::vector<double> nearest(static_cast<size_t>(gw) * gh, std::numeric_limits<double>::infinity());
  for (const PointSample& s : samples) {
    double& n = nearest[static_cast<size_t>(s.y / cell) * gw + s.x / cell];
    n = std::min(n, s.z);
  }
  std::vector<PointSample> out;
  for (const PointSample& s : samples) {
    const int cx = s.x / cell, cy = s.y / cell;
    double closest = std::numeric_limits<double>::infinity();
    for (int y = std::max(0, cy - 1); y <= std::min(gh - 1, cy + 1); ++y)
      for (int x = std::max(0, cx - 1); x <= std::min(gw - 1, cx + 1); ++x)
        closest = std::min(closest, nearest[static_cast<size_t>(y) * gw + x]);
    if (s.z <= closest * front) out.push_back(s);
  }
  return out;
}

// The points a view sees: those not hidden (front_points), and their mean spacing in pixels over
// the `used_pixels` they fall on.
struct VisiblePoints {
  std::vector<PointSample> front;
  double spacing = 1;
};

VisiblePoints visible_points(const std::vector<PointSample>& samples, int64_t used_pixels, double front, int w,
                             int h) {
  VisiblePoints v;
  v.spacing = std::sqrt(static_cast<double>(std::max<int64_t>(used_pixels, 1)) / samples.size());
  v.front = front_points(samples, v.spacing, front, w, h);
  return v;
}

// The log-depth correction each pixel of a w x h view needs beyond its scale `scale`: the visible
// points' remaining log ratios averaged with Gaussian weights `detail` point spacings wide, pulled
// back to 0 by `prior` points' weight where few are near (a normalised convolution, on a grid a
// quarter of that width, bilinear between its cells).
torch::Tensor detail_correction(const VisiblePoints& visible, double scale, int w, int h,
                                const DepthDetailOptions& options) {
  const double sigma = std::max(1.0, options.detail * visible.spacing);
  const int cell = std::max(1, static_cast<int>(sigma / 4));
  const int gw = (w + cell - 1) / cell, gh = (h + cell - 1) / cell;
  cv::Mat sum = cv::Mat::zeros(gh, gw, CV_64F), weight = cv::Mat::zeros(gh, gw, CV_64F);
  const double limit = std::log(options.max_ratio), log_scale = std::log(scale);
  for (const PointSample& s : visible.front) {
    const int gy = s.y / cell, gx = s.x / cell;
    sum.at<double>(gy, gx) += std::clamp(std::log(s.z / s.predicted) - log_scale, -limit, limit);
    weight.at<double>(gy, gx) += 1;
  }
  const double grid_sigma = sigma / cell;
  const int radius = static_cast<int>(std::ceil(3 * grid_sigma));
  cv::Mat kernel(2 * radius + 1, 1, CV_64F);
  for (int k = -radius; k <= radius; ++k)
    kernel.at<double>(k + radius) = std::exp(-0.5 * k * k / (grid_sigma * grid_sigma));
  // Separable, zeros beyond the picture (OpenCV's: the grid is a pixel a cell where points are
  // dense, and LibTorch's conv2d took 45-260 ms a view there at 904 x 512).
  auto blur = [&](const cv::Mat& m) {
    cv::Mat out;
    cv::sepFilter2D(m, out, CV_64F, kernel, kernel, cv::Point(-1, -1), 0, cv::BORDER_CONSTANT);
    return out;
  };
  cv::Mat ratio = blur(sum) / (blur(weight) + options.prior), ratio32;
  ratio.convertTo(ratio32, CV_32F);
  const torch::Tensor grid = torch::from_blob(ratio32.ptr<float>(), {1, 1, gh, gw}, torch::kFloat32).clone();
  // Cell centres at (i + 0.5) * cell: align_corners = false maps the grid over the picture.
  const torch::Tensor full = torch::upsample_bilinear2d(grid, {gh * cell, gw * cell}, false)[0][0];
  return full.narrow(0, 0, h).narrow(1, 0, w);
}

// The mask (H, W) with its edge ramped over a 32nd of the height each way, so that the region's
// wider correction meets the rest without a step.
torch::Tensor soft_mask(const Image& mask) {
  const torch::Tensor m =
      torch::from_blob(const_cast<float*>(mask.pixels.data()), {1, 1, mask.height, mask.width}, torch::kFloat32);
  const int r = std::max(1, mask.height / 32);
  // A box filter, one direction at a time (the same mean over a rectangle, 2r+1 times fewer sums).
  const torch::Tensor rows = torch::avg_pool2d(m, {1, 2 * r + 1}, {1, 1}, {0, r}, false, false);
  return torch::avg_pool2d(rows, {2 * r + 1, 1}, {1, 1}, {r, 0}, false, false).view({mask.height, mask.width});
}

// What one view's alignment found: its scale and, with detail, the factor of each pixel.
struct ViewAlignment {
  DepthAlignment report;
  torch::Tensor factor;  // (H, W) on the CPU, or undefined for the scale alone
};

ViewAlignment align_view(const torch::Tensor& predicted_depth, const PreparedView& view, const Camera& camera,
                         const std::vector<Eigen::Vector3d>& points, const DepthDetailOptions& options,
                         int64_t min_points) {
  ViewAlignment out;
  out.report.view = view.name;
  const torch::Tensor depth = predicted_depth.to(torch::kCPU, torch::kFloat32).contiguous();
  Image outside(view.rgb.width, view.rgb.height, 1, 1.f);
  if (view.mask)
    for (size_t i = 0; i < outside.pixels.size(); ++i) outside.pixels[i] = view.mask->pixels[i] <= 0.5f;
  const std::vector<PointSample> samples = point_samples(depth.data_ptr<float>(), outside, camera, points);
  // The scale from a ring around the mask where there is one: the region's Gaussians are what an
  // edit shows, and the scale right next to them is theirs. A ring of a sixteenth of the height:
  // held-out rooms 23.98 dB masked against 23.75 with every pixel outside the mask and 23.80 with
  // a sixth (the network's own depth: 23.88).
  std::vector<PointSample> deciding;
  if (view.mask) {
    const int r = std::max(4, view.rgb.height / 16);
    const Image grown = dilate_mask(*view.mask, 1, 2 * r + 1);
    for (const PointSample& s : samples)
      if (grown.at(s.y, s.x) > 0.5f) deciding.push_back(s);
  }
  if (static_cast<int64_t>(deciding.size()) < min_points) deciding = samples;
  out.report.points = static_cast<int64_t>(deciding.size());
  const double scale = median_ratio(deciding);
  if (out.report.points < min_points || !std::isfinite(scale) || !(scale > 0)) return out;
  out.report.scale = scale;
  if (options.detail > 0) {
    int64_t used = 0;
    for (float u : outside.pixels) used += u > 0.5f;
    const int w = camera.K.width, h = camera.K.height;
    const VisiblePoints visible = visible_points(samples, used, options.front, w, h);
    torch::Tensor log_correction = detail_correction(visible, scale, w, h, options);
    if (view.mask && options.region_factor != 1) {
      DepthDetailOptions wide = options;
      wide.detail *= options.region_factor;
      const torch::Tensor region = soft_mask(*view.mask);
      log_correction = log_correction * (1 - region) +
                       detail_correction(visible, scale, w, h, wide) * region;
    }
    out.report.detail_mean = log_correction.abs().mean().item<double>();
    out.factor = log_correction.exp() * scale;
  }
  return out;
}

}  // namespace

std::vector<DepthAlignment> align_depth_to_points(GaussianMaps& maps, const SceneInput& input,
                                                  const std::vector<Eigen::Vector3d>& points,
                                                  const DepthDetailOptions& options, int64_t min_points) {
  std::vector<Eigen::Vector3d> normalized;
  normalized.reserve(points.size());
  for (const Eigen::Vector3d& p : points) normalized.push_back(input.normalization.apply(p));
  std::vector<DepthAlignment> out;
  torch::InferenceMode inference;  // the maps are the network's inference tensors
  const int64_t views = static_cast<int64_t>(input.views.size());
  std::vector<torch::Tensor> depths;
  std::vector<Camera> cameras;
  for (int64_t v = 0; v < views; ++v) {
    depths.push_back(maps.depth[0][v][0]);
    cameras.push_back(input.normalization.apply(input.views[static_cast<size_t>(v)].camera));
  }
  // The views side by side: each is the CPU's work of tens of milliseconds (eval on a GPU machine
  // waited 155-213 ms for four views at 904 x 512 one after another).
  std::vector<ViewAlignment> aligned(static_cast<size_t>(views));
  parallel_dynamic(views, thread_plan().cores, [&](int64_t v) {
    torch::InferenceMode per_thread;
    const size_t i = static_cast<size_t>(v);
    aligned[i] = align_view(depths[i], input.views[i], cameras[i], normalized, options, min_points);
  });
  for (size_t v = 0; v < input.views.size(); ++v) {
    const int64_t vi = static_cast<int64_t>(v);
    const Camera& camera = cameras[v];
    const ViewAlignment& a = aligned[v];
    out.push_back(a.report);
    if (a.report.scale == 1.0) continue;
    const Eigen::Vector3d o = camera.center();
    const torch::Tensor centre =
        torch::tensor({o.x(), o.y(), o.z()}, torch::kFloat64).to(maps.xyz.device(), maps.xyz.scalar_type()).view({3, 1, 1});
    const torch::Tensor factor =
        a.factor.defined() ? a.factor.to(maps.xyz.device(), maps.xyz.scalar_type()).unsqueeze(0)
                           : torch::full({1, 1, 1}, a.report.scale, maps.xyz.options());
    // In place on the maps' rows of this view: the Gaussians are views of the maps.
    maps.depth[0][vi].mul_(factor);
    maps.xyz[0][vi].sub_(centre).mul_(factor).add_(centre);
    maps.scale[0][vi].mul_(factor);
  }
  return out;
}

double median_depth_ratio(const torch::Tensor& measured, const torch::Tensor& predicted,
                          const std::vector<torch::Tensor>& where, int64_t min_pixels) {
  const torch::Tensor ratio = measured / predicted.to(measured.device()).clamp_min(1e-12);
  for (const torch::Tensor& pixels : where) {
    const torch::Tensor r = ratio.index({pixels.to(ratio.device())});
    if (r.numel() >= min_pixels) return r.median().item<double>();
  }
  return 1.0;
}

}  // namespace ii
