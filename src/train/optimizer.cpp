#include "train/optimizer.h"

#include <cmath>

#include "common/error.h"

namespace ii {

bool official_decays(const std::string& name, const torch::Tensor& parameter) {
  const std::string bias = ".bias";
  const bool is_bias = name.size() >= bias.size() && name.compare(name.size() - bias.size(), bias.size(), bias) == 0;
  return parameter.dim() >= 2 && !is_bias;
}

AdamW::AdamW(std::vector<torch::Tensor> parameters, std::vector<bool> decay, AdamWOptions options)
    : parameters_(std::move(parameters)), decay_(std::move(decay)), options_(options) {
  if (decay_.size() != parameters_.size())
    fail("AdamW: {} decay flags for {} parameters", decay_.size(), parameters_.size());
  for (const torch::Tensor& p : parameters_) {
    exp_avg_.push_back(torch::zeros_like(p, torch::MemoryFormat::Contiguous));
    exp_avg_sq_.push_back(torch::zeros_like(p, torch::MemoryFormat::Contiguous));
  }
}

void AdamW::step(double lr) {
  torch::NoGradGuard no_grad;
  ++steps_;
  const double t = static_cast<double>(steps_);
  const double bias1 = 1.0 - std::pow(options_.beta1, t);
  const double bias2_sqrt = std::sqrt(1.0 - std::pow(options_.beta2, t));
  const double step_size = lr / bias1;
  for (size_t i = 0; i < parameters_.size(); ++i) {
    torch::Tensor& p = parameters_[i];
    const torch::Tensor g = p.grad();
    if (!g.defined()) continue;
    if (decay_[i] && options_.weight_decay != 0) p.mul_(1.0 - lr * options_.weight_decay);
    exp_avg_[i].mul_(options_.beta1).add_(g, 1.0 - options_.beta1);
    exp_avg_sq_[i].mul_(options_.beta2).addcmul_(g, g, 1.0 - options_.beta2);
    const torch::Tensor denom = (exp_avg_sq_[i].sqrt() / bias2_sqrt).add_(options_.eps);
    p.addcdiv_(exp_avg_[i], denom, -step_size);
  }
}

void AdamW::zero_grad() {
  for (torch::Tensor& p : parameters_)
    if (p.grad().defined()) p.mutable_grad() = torch::Tensor();
}

void AdamW::load_state(int64_t steps, const std::vector<torch::Tensor>& exp_avg,
                       const std::vector<torch::Tensor>& exp_avg_sq) {
  if (exp_avg.size() != parameters_.size() || exp_avg_sq.size() != parameters_.size())
    fail("AdamW state: {} / {} moments for {} parameters", exp_avg.size(), exp_avg_sq.size(), parameters_.size());
  for (size_t i = 0; i < parameters_.size(); ++i)
    if (exp_avg[i].sizes() != parameters_[i].sizes() || exp_avg_sq[i].sizes() != parameters_[i].sizes())
      fail("AdamW state: moments of parameter {} do not have its shape", i);
  torch::NoGradGuard no_grad;
  for (size_t i = 0; i < parameters_.size(); ++i) {
    exp_avg_[i].copy_(exp_avg[i]);
    exp_avg_sq_[i].copy_(exp_avg_sq[i]);
  }
  steps_ = steps;
}

ClipStats clip_gradients_per_tensor(const std::vector<torch::Tensor>& parameters, double max_norm) {
  torch::NoGradGuard no_grad;
  ClipStats stats;
  double sum_sq = 0;
  for (const torch::Tensor& p : parameters) {
    torch::Tensor g = p.grad();
    if (!g.defined()) continue;
    if (!torch::isfinite(g).all().item<bool>()) {
      ++stats.nonfinite_tensors;
      g.nan_to_num_(0.0, 0.0, 0.0);
    }
    const double norm = g.norm(2).item<double>();
    sum_sq += norm * norm;
    if (norm > max_norm) {
      ++stats.clipped_tensors;
      g.mul_(max_norm / (norm + 1e-6));
    }
  }
  stats.norm = std::sqrt(sum_sq);
  return stats;
}

}  // namespace ii
