#include "refine/densify.h"

#include <algorithm>
#include <cmath>

namespace ii {

int64_t DensifyDecision::added() const { return clone.sum().item<int64_t>() + split.sum().item<int64_t>(); }

DensifyDecision decide_densification(const torch::Tensor& mean_grad, const torch::Tensor& max_scale,
                                     const torch::Tensor& opacity, double extent, int64_t max_gaussians,
                                     const DensifyOptions& options) {
  torch::NoGradGuard no_grad;
  DensifyDecision d;
  d.prune = opacity < options.min_opacity;
  torch::Tensor candidates = (mean_grad >= options.grad_threshold).logical_and(d.prune.logical_not());
  const int64_t n = mean_grad.size(0);
  const int64_t room = std::max<int64_t>(0, max_gaussians - (n - d.prune.sum().item<int64_t>()));
  const int64_t wanted = candidates.sum().item<int64_t>();
  if (wanted > room) {
    // The `room` largest gradients among the candidates (ties: the lower index first).
    const torch::Tensor score = torch::where(candidates, mean_grad, torch::full_like(mean_grad, -1));
    const torch::Tensor order = std::get<1>(score.sort(/*stable=*/true, /*dim=*/0, /*descending=*/true));
    candidates = torch::zeros_like(candidates);
    candidates.index_put_({order.narrow(0, 0, room)}, true);
  }
  const torch::Tensor large = max_scale > options.dense_fraction * extent;
  d.clone = candidates.logical_and(large.logical_not());
  d.split = candidates.logical_and(large);
  return d;
}

std::pair<torch::Tensor, torch::Tensor> split_centres(const torch::Tensor& means, const torch::Tensor& scales,
                                                      const torch::Tensor& quats) {
  torch::NoGradGuard no_grad;
  const torch::Tensor q = quats / quats.norm(2, 1, true).clamp_min(1e-12);
  const torch::Tensor w = q.select(1, 0), x = q.select(1, 1), y = q.select(1, 2), z = q.select(1, 3);
  // Columns of the rotation matrix: the Gaussian's axes in the world.
  const torch::Tensor axes = torch::stack(
      {torch::stack({1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)}, 1),
       torch::stack({2 * (x * y - w * z), 1 - 2 * (x * x + z * z), 2 * (y * z + w * x)}, 1),
       torch::stack({2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)}, 1)},
      1);  // (M, axis, xyz)
  const auto [largest, axis] = scales.max(1);
  const torch::Tensor direction = axes.gather(1, axis.view({-1, 1, 1}).expand({-1, 1, 3})).squeeze(1);
  const double offset = std::sqrt(1 - 1 / (kSplitScaleDivisor * kSplitScaleDivisor));  // 0.78
  const torch::Tensor step = direction * (offset * largest).unsqueeze(1);
  return {means + step, means - step};
}

torch::Tensor split_log_scales(const torch::Tensor& log_scales) {
  torch::NoGradGuard no_grad;
  const torch::Tensor longest = log_scales.argmax(1, true);
  return log_scales.scatter(1, longest, log_scales.gather(1, longest) - std::log(kSplitScaleDivisor));
}

}  // namespace ii
