#include "model/depth_alignment.h"

#include <algorithm>
#include <cmath>

#include "common/torch.h"
#include "data/masks.h"

namespace ii {

namespace {

// The median of the ratios of the points' camera z to the predicted depth at their pixels where
// `use` (the view's size) is set; `count` gets how many there were.
double median_ratio(const torch::Tensor& depth, const Image& use, const Camera& camera,
                    const std::vector<Eigen::Vector3d>& points, int64_t& count) {
  const torch::Tensor d = depth.to(torch::kCPU, torch::kFloat32).contiguous();
  const float* dp = d.data_ptr<float>();
  const int w = camera.K.width, h = camera.K.height;
  const Eigen::Matrix4d w2c = camera.w2c_opencv();
  std::vector<double> ratios;
  for (const Eigen::Vector3d& p : points) {
    const Eigen::Vector3d c = w2c.block<3, 3>(0, 0) * p + w2c.block<3, 1>(0, 3);
    if (!(c.z() > 0)) continue;
    const double u = camera.K.fx * c.x() / c.z() + camera.K.cx, v = camera.K.fy * c.y() / c.z() + camera.K.cy;
    if (!(u >= 0 && v >= 0 && u < w && v < h)) continue;
    const int x = static_cast<int>(u), y = static_cast<int>(v);
    if (use.at(y, x) < 0.5f) continue;
    const double predicted = dp[static_cast<size_t>(y) * w + x];
    if (predicted > 0 && std::isfinite(predicted)) ratios.push_back(c.z() / predicted);
  }
  count = static_cast<int64_t>(ratios.size());
  if (ratios.empty()) return 1.0;
  const auto mid = ratios.begin() + static_cast<std::ptrdiff_t>(ratios.size() / 2);
  std::nth_element(ratios.begin(), mid, ratios.end());
  return *mid;
}

}  // namespace

std::vector<DepthAlignment> align_depth_to_points(GaussianMaps& maps, const SceneInput& input,
                                                  const std::vector<Eigen::Vector3d>& points, int64_t min_points) {
  std::vector<Eigen::Vector3d> normalized;
  normalized.reserve(points.size());
  for (const Eigen::Vector3d& p : points) normalized.push_back(input.normalization.apply(p));
  std::vector<DepthAlignment> out;
  for (size_t v = 0; v < input.views.size(); ++v) {
    const int64_t vi = static_cast<int64_t>(v);
    const Camera camera = input.normalization.apply(input.views[v].camera);
    DepthAlignment a{input.views[v].name, 1.0, 0};
    const PreparedView& view = input.views[v];
    // Outside the mask; where there is one, on a ring around it first: the region's Gaussians
    // are what an edit shows, and the scale right next to them is theirs.
    Image outside(view.rgb.width, view.rgb.height, 1, 1.f);
    double s = 1.0;
    if (view.mask) {
      // A ring of a sixteenth of the height: held-out rooms 23.98 dB masked against 23.75 with every
      // pixel outside the mask and 23.80 with a sixth (the network's own depth: 23.88).
      const int r = std::max(4, view.rgb.height / 16);
      const Image grown = dilate_mask(*view.mask, 1, 2 * r + 1);
      Image ring = outside;
      for (size_t i = 0; i < ring.pixels.size(); ++i) ring.pixels[i] = grown.pixels[i] > 0.5f && view.mask->pixels[i] <= 0.5f;
      s = median_ratio(maps.depth[0][vi][0], ring, camera, normalized, a.points);
    }
    if (a.points < min_points) {
      if (view.mask)
        for (size_t i = 0; i < outside.pixels.size(); ++i) outside.pixels[i] = view.mask->pixels[i] <= 0.5f;
      s = median_ratio(maps.depth[0][vi][0], outside, camera, normalized, a.points);
    }
    if (a.points >= min_points && std::isfinite(s) && s > 0) a.scale = s;
    out.push_back(a);
  }
  for (size_t v = 0; v < input.views.size(); ++v) {
    const int64_t vi = static_cast<int64_t>(v);
    const DepthAlignment& a = out[v];
    if (a.scale == 1.0) continue;
    const Camera camera = input.normalization.apply(input.views[v].camera);
    torch::InferenceMode inference;  // the maps are the network's inference tensors
    const Eigen::Vector3d o = camera.center();
    const torch::Tensor centre =
        torch::tensor({o.x(), o.y(), o.z()}, torch::kFloat64).to(maps.xyz.device(), maps.xyz.scalar_type()).view({3, 1, 1});
    // In place on the maps' rows of this view: the Gaussians are views of the maps.
    maps.depth[0][vi].mul_(a.scale);
    maps.xyz[0][vi].sub_(centre).mul_(a.scale).add_(centre);
    maps.scale[0][vi].mul_(a.scale);
  }
  return out;
}

}  // namespace ii
