#pragma once
// The official optimiser (spec §6.5): AdamW with decoupled weight decay, and gradient
// clipping per parameter tensor (not by the global norm) with non-finite values zeroed.
#include <cstdint>
#include <string>
#include <vector>

#include "common/torch.h"

namespace ii {

struct AdamWOptions {
  double beta1 = 0.9, beta2 = 0.95;
  double eps = 1e-8;
  double weight_decay = 0.05;
};

// The official decay rule: parameters with at least 2 dimensions whose name does not end in
// ".bias" are decayed, others not.
bool official_decays(const std::string& name, const torch::Tensor& parameter);

// torch.optim.AdamW's update, per parameter p with gradient g at step t (1-based):
//   p ← p·(1 − lr·wd);  m ← β1 m + (1 − β1) g;  v ← β2 v + (1 − β2) g²
//   p ← p − lr/(1 − β1ᵗ) · m / (√v / √(1 − β2ᵗ) + eps)
// Parameters without a gradient are left alone (their moments too).
class AdamW {
 public:
  // `decay[i]` says whether parameters[i] gets weight decay.
  AdamW(std::vector<torch::Tensor> parameters, std::vector<bool> decay, AdamWOptions options = {});

  void step(double lr);
  void zero_grad();

  int64_t steps() const { return steps_; }
  const AdamWOptions& options() const { return options_; }
  const std::vector<torch::Tensor>& parameters() const { return parameters_; }
  // Moments, one per parameter (zeros before the first step).
  const std::vector<torch::Tensor>& exp_avg() const { return exp_avg_; }
  const std::vector<torch::Tensor>& exp_avg_sq() const { return exp_avg_sq_; }
  // Restores the state written by a checkpoint (shapes must match; throws Error naming the
  // parameter index otherwise).
  void load_state(int64_t steps, const std::vector<torch::Tensor>& exp_avg, const std::vector<torch::Tensor>& exp_avg_sq);

 private:
  std::vector<torch::Tensor> parameters_;
  std::vector<bool> decay_;
  AdamWOptions options_;
  std::vector<torch::Tensor> exp_avg_, exp_avg_sq_;
  int64_t steps_ = 0;
};

struct ClipStats {
  double norm = 0;            // global L2 norm of all gradients after zeroing, before clipping
  int clipped_tensors = 0;    // tensors whose norm exceeded max_norm
  int nonfinite_tensors = 0;  // tensors that held NaN or ±Inf values
};

// Per tensor: NaN/±Inf set to 0, then if ‖g‖₂ > max_norm, g ← g · max_norm/(‖g‖₂ + 1e-6)
// (torch's clip_grad_norm_ applied to each tensor on its own). Undefined gradients are skipped.
ClipStats clip_gradients_per_tensor(const std::vector<torch::Tensor>& parameters, double max_norm = 1.0);

}  // namespace ii
