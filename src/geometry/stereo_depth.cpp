#include "geometry/stereo_depth.h"

#include <algorithm>
#include <cmath>

#include <Eigen/LU>

#include "common/error.h"
#include "geometry/sweep_correlation.h"
#include "tensor/camera_projection.h"
#include "tensor/image_tensor.h"

namespace ii {

namespace {

// Sums of (B, C, H, W) over `window` neighbours along `dim` (3: rows' neighbours, 2: columns'),
// zero beyond the border: differences of a running sum, two operations whatever the window.
torch::Tensor window_sums(const torch::Tensor& x, int window, int64_t dim) {
  const int64_t half = window / 2;
  const std::vector<int64_t> pad =
      dim == 3 ? std::vector<int64_t>{half + 1, half} : std::vector<int64_t>{0, 0, half + 1, half};
  const torch::Tensor running = torch::constant_pad_nd(x, pad, 0).cumsum(dim);
  const int64_t n = x.size(dim);
  return running.narrow(dim, window, n) - running.narrow(dim, 0, n);
}

// The mean over a window x window square around each pixel of (B, C, H, W); near the border over
// the part inside the picture.
torch::Tensor box_mean(const torch::Tensor& x, int window) {
  const torch::Tensor ones = torch::ones({1, 1, x.size(2), x.size(3)}, x.options());
  const torch::Tensor count = window_sums(window_sums(ones, window, 3), window, 2);
  return window_sums(window_sums(x, window, 3), window, 2) / count;
}

// A photo as (1, 1, h, w) grey levels at the matching size.
torch::Tensor grey_at(const Image& photo, int64_t height, int64_t width) {
  torch::Tensor rgb = image_to_tensor(photo);
  if (rgb.size(2) != height || rgb.size(3) != width)
    rgb = torch::adaptive_avg_pool2d(rgb, {height, width});  // each pixel the mean of its area
  const torch::Tensor weights = torch::tensor({0.299f, 0.587f, 0.114f}).view({1, 3, 1, 1});
  return (rgb.narrow(1, 0, 3) * weights).sum(1, /*keepdim=*/true);
}

// Camera-frame directions (h * w, 3) through a camera's pixel centres, z = 1 (OpenCV axes).
torch::Tensor pixel_directions(const Camera& camera) {
  const Intrinsics& K = camera.K;
  const torch::Tensor x = (torch::arange(K.width, torch::kFloat32) + 0.5f - K.cx) / K.fx;
  const torch::Tensor y = (torch::arange(K.height, torch::kFloat32) + 0.5f - K.cy) / K.fy;
  const std::vector<torch::Tensor> grid = torch::meshgrid({y, x}, "ij");
  return torch::stack({grid[1].flatten(), grid[0].flatten(), torch::ones({K.width * K.height})}, 1);
}

// A picture as the sweep compares it: grey levels and their window statistics.
struct Matching {
  torch::Tensor grey;       // (1, 1, h, w)
  torch::Tensor mean;       // its window means
  torch::Tensor deviation;  // its window standard deviations
};

Matching matching_picture(const Image& photo, const Camera& camera, int window) {
  Matching m;
  m.grey = grey_at(photo, camera.K.height, camera.K.width);
  m.mean = box_mean(m.grey, window);
  m.deviation = (box_mean(m.grey * m.grey, window) - m.mean * m.mean).clamp_min(0).sqrt();
  return m;
}

// The mean over the first dimension of its best two (of three: the sum less the least).
torch::Tensor best_two_mean(const torch::Tensor& all) {
  if (all.size(0) <= 2) return all.mean(0);
  if (all.size(0) == 3) return (all.sum(0) - std::get<0>(all.min(0))) * 0.5f;
  return std::get<0>(all.topk(2, 0)).mean(0);
}

// One view's depth (h, w; 0 = unknown) from its correlations with every other view, tried at
// `guide` (h, w) times each of `factors` (D, increasing).
torch::Tensor sweep(const std::vector<Matching>& pictures, const std::vector<Camera>& cameras, size_t reference,
                    const torch::Tensor& guide, const torch::Tensor& log_factors, const StereoOptions& options) {
  const torch::Tensor depths = log_factors.exp().unsqueeze(1) * guide.flatten().unsqueeze(0);  // (D, N)
  std::vector<torch::Tensor> volumes;
  for (size_t s = 0; s < pictures.size(); ++s)
    if (s != reference)
      volumes.push_back(sweep_correlation(pictures[reference].grey[0][0], cameras[reference], pictures[s].grey[0][0],
                                          cameras[s], depths, options.window));
  const torch::Tensor all = torch::stack(volumes);  // (S, D, h, w)
  // The best two views' correlations: a third may see something else in front of the point.
  const torch::Tensor score = best_two_mean(all);  // (D, h, w)
  const auto [best, index] = score.max(0);
  const int64_t D = score.size(0);
  // The peak between its neighbours (a parabola through three depths), in log depth.
  const torch::Tensor before = score.gather(0, (index - 1).clamp_min(0).unsqueeze(0)).squeeze(0);
  const torch::Tensor after = score.gather(0, (index + 1).clamp_max(D - 1).unsqueeze(0)).squeeze(0);
  const torch::Tensor curvature = before + after - 2 * best;
  const torch::Tensor offset = torch::where(curvature.lt(-1e-6f), 0.5f * (before - after) / curvature,
                                            torch::zeros_like(best))
                                   .clamp(-0.5, 0.5);
  const double step = (log_factors[1] - log_factors[0]).item<double>();
  const torch::Tensor depth = guide * (log_factors.index({index}) + offset * step).exp();
  // Known: a clear match inside the range (a peak at its end may lie beyond it) on texture.
  const torch::Tensor known = best.gt(options.min_ncc)
                                  .logical_and(index.gt(0))
                                  .logical_and(index.lt(D - 1))
                                  .logical_and(guide.gt(0))
                                  .logical_and(pictures[reference].deviation[0][0].gt(0.01f));
  return torch::where(known, depth, torch::zeros_like(depth));
}

// Keeps the depths that another view's own sweep agrees with where the point lands in it.
torch::Tensor agreed(const std::vector<torch::Tensor>& depths, const std::vector<Camera>& cameras, size_t view,
                     double tolerance) {
  const torch::Tensor depth = depths[view].flatten();
  const torch::Tensor points_camera = pixel_directions(cameras[view]) * depth.unsqueeze(1);
  const torch::Tensor points = transformed(cameras[view].w2c_opencv().inverse(), points_camera);
  torch::Tensor any = torch::zeros_like(depth, torch::kBool);
  for (size_t s = 0; s < depths.size(); ++s) {
    if (s == view) continue;
    const PixelHit hit = project(cameras[s], points);
    const torch::Tensor there = depths[s].flatten().index({hit.index});
    any = any.logical_or(hit.inside.logical_and(there.gt(0)).logical_and(
        (hit.z - there).abs().le(tolerance * there)));
  }
  return torch::where(any.logical_and(depth.gt(0)), depth, torch::zeros_like(depth)).view_as(depths[view]);
}

// (h, w) depth brought to (H, W): bilinear where every contributing depth is known and they
// agree (across an edge no surface lies between them).
torch::Tensor brought_up(const torch::Tensor& depth, int64_t height, int64_t width, double tolerance) {
  const torch::Tensor d = depth.view({1, 1, depth.size(0), depth.size(1)});
  const torch::Tensor known = d.gt(0).to(torch::kFloat32);
  const torch::Tensor farthest = torch::max_pool2d(d, {3, 3}, {1, 1}, {1, 1});
  const torch::Tensor nearest_inverse =
      torch::max_pool2d(torch::where(d.gt(0), d.reciprocal(), torch::zeros_like(d)), {3, 3}, {1, 1}, {1, 1});
  // Within the 3 x 3 neighbourhood the depths stay within a few tolerances of each other.
  const torch::Tensor smooth = (farthest * nearest_inverse).le(1 + 4 * tolerance).to(torch::kFloat32) * known;
  auto up = [&](const torch::Tensor& x) { return torch::upsample_bilinear2d(x, {height, width}, false); };
  const torch::Tensor depth_up = up(d), usable = up(smooth);
  return torch::where(usable.ge(0.999f), depth_up, torch::zeros_like(depth_up))[0][0];
}

}  // namespace

std::vector<torch::Tensor> stereo_depth(const std::vector<Image>& photos, const std::vector<Camera>& cameras,
                                        const std::vector<torch::Tensor>& guides, const StereoOptions& options) {
  if (photos.size() != cameras.size() || guides.size() != cameras.size() || photos.size() < 2)
    throw Error("stereo depth needs two or more photos with a camera and a guiding depth each");
  if (!(options.spread > 1)) throw Error("stereo depth needs a spread above 1");
  torch::NoGradGuard no_grad;
  // Matched at about options.rows rows: the sweep costs the same at every working size.
  const double rows = std::max(1, options.rows);
  const int scale = std::max(1, static_cast<int>(std::lround(cameras.front().K.height / rows)));
  std::vector<Camera> small;
  std::vector<Matching> pictures;
  std::vector<torch::Tensor> small_guides;
  for (size_t v = 0; v < photos.size(); ++v) {
    small.push_back(cameras[v].resized(std::max(1, cameras[v].K.width / scale),
                                       std::max(1, cameras[v].K.height / scale)));
    pictures.push_back(matching_picture(photos[v], small.back(), options.window));
    const torch::Tensor guide = guides[v].to(torch::kCPU, torch::kFloat32).view({1, 1, guides[v].size(0), -1});
    const torch::Tensor log_guide =
        torch::adaptive_avg_pool2d(guide.clamp_min(1e-6).log(), {small.back().K.height, small.back().K.width});
    // Smoothed: the sweep tries each window's pixels at their own depths, and the network's depth
    // is bumpy from pixel to pixel (unsmoothed, scene 1's views were known at 5 % instead of 45 %).
    const int window = 2 * static_cast<int>(options.guide_smoothing * small.back().K.height / 2) + 1;
    small_guides.push_back(box_mean(log_guide, window).exp()[0][0]);
  }
  const double reach = std::log(options.spread);
  const torch::Tensor log_factors = torch::linspace(-reach, reach, std::max(3, options.planes), torch::kFloat32);
  std::vector<torch::Tensor> swept;
  for (size_t v = 0; v < photos.size(); ++v)
    swept.push_back(sweep(pictures, small, v, small_guides[v], log_factors, options));
  std::vector<torch::Tensor> out;
  for (size_t v = 0; v < photos.size(); ++v) {
    const torch::Tensor kept = agreed(swept, small, v, options.consistency);
    out.push_back(brought_up(kept, cameras[v].K.height, cameras[v].K.width, options.consistency));
  }
  return out;
}

}  // namespace ii
