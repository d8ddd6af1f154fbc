#include "render/visualize.h"

#include <algorithm>

#include "data/image_ops.h"

namespace ii {

Image depth_colours(const torch::Tensor& depth) {
  const torch::Tensor d = depth.to(torch::kCPU, torch::kFloat32).contiguous();
  const float lo = d.min().item<float>(), hi = d.max().item<float>();
  const float* p = d.data_ptr<float>();
  std::vector<uint8_t> levels(static_cast<size_t>(d.numel()));
  for (size_t i = 0; i < levels.size(); ++i)
    levels[i] = static_cast<uint8_t>(255.f * (1.f - (p[i] - lo) / std::max(hi - lo, 1e-6f)));
  return inferno_colours(levels, static_cast<int>(d.size(1)), static_cast<int>(d.size(0)));
}

Image VideoDepthColours::operator()(const torch::Tensor& depth, const torch::Tensor& alpha) {
  const torch::Tensor d = depth.reshape({-1}).to(torch::kCPU, torch::kFloat32).contiguous();
  const torch::Tensor a = alpha.reshape({-1}).to(torch::kCPU, torch::kFloat32).contiguous();
  const torch::Tensor hit = a > 0.5;
  if (!have_range_ && hit.any().item<bool>()) {
    const torch::Tensor v = d.index({hit});
    lo_ = v.quantile(0.02).item<float>();
    hi_ = v.quantile(0.98).item<float>();
    if (!(hi_ > lo_)) hi_ = lo_ + 1e-3f;
    have_range_ = true;
  }
  const int h = static_cast<int>(depth.size(0)), w = static_cast<int>(depth.size(1));
  const float* dp = d.data_ptr<float>();
  std::vector<uint8_t> levels(static_cast<size_t>(h) * w);
  for (size_t i = 0; i < levels.size(); ++i) {
    const float t = have_range_ ? std::clamp((dp[i] - lo_) / (hi_ - lo_), 0.f, 1.f) : 1.f;
    levels[i] = static_cast<uint8_t>(255.f * (1.f - t));
  }
  Image out = inferno_colours(levels, w, h);
  const float* ap = a.data_ptr<float>();
  for (size_t i = 0; i < levels.size(); ++i)
    if (ap[i] < 0.5f) std::fill_n(out.pixels.begin() + i * 3, 3, 0.f);
  return out;
}

}  // namespace ii
