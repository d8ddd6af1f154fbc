#pragma once
// 3DGS's adaptive density control, as pure functions on per-Gaussian values so that tests can
// state exact expectations: Gaussians whose mean view-space positional gradient is large are
// cloned (small ones) or split in two (large ones); nearly transparent ones are pruned; the
// count never exceeds a cap (the largest gradients win).
#include <cstdint>

#include "common/torch.h"

namespace ii {

struct DensifyOptions {
  bool enabled = true;
  double grad_threshold = 2e-4;  // mean |dL/d(projected centre)| in NDC units, 3DGS's
  double dense_fraction = 0.01;  // largest scale / scene extent at or below: clone; above: split
  double min_opacity = 0.005;    // pruned below
  // Cap = start count x (1 + this), unless max_gaussians is set. 8x: a 10-minute statue run settles near
  // 310 k Gaussians from 38.5 k (590 MB); at 2x its trees stayed blurred (23.75 dB held out against
  // 24.32, 2026-11-26, f8195f0; docs/benchmarks.md, "Refinement (`--refine`)").
  double max_growth = 7.0;
  int64_t max_gaussians = 0;
};

struct DensifyDecision {
  torch::Tensor clone, split, prune;  // bool (N), disjoint
  int64_t added() const;              // net Gaussians added: clones + splits (one becomes two)
};

// mean_grad: the mean view-space gradient per Gaussian (0 where never seen); max_scale: the
// largest standard deviation; opacity in (0, 1).
DensifyDecision decide_densification(const torch::Tensor& mean_grad, const torch::Tensor& max_scale,
                                     const torch::Tensor& opacity, double extent, int64_t max_gaussians,
                                     const DensifyOptions& options);

// The children of split Gaussians lie along the parent's longest axis: that axis's σ / 1.6,
// the other two kept, centres at ±0.78 σ (σ² = σ'² + d²: the pair spreads as its parent did).
// 3DGS divides all three scales and samples the centres at random; in a run of minutes the
// image must not jump at each split. Returns the centres of the first and of the second
// children, each (M, 3), and the children's log scales (M, 3) from the parents'.
std::pair<torch::Tensor, torch::Tensor> split_centres(const torch::Tensor& means, const torch::Tensor& scales,
                                                      const torch::Tensor& quats);
torch::Tensor split_log_scales(const torch::Tensor& log_scales);
constexpr double kSplitScaleDivisor = 1.6;

}  // namespace ii
