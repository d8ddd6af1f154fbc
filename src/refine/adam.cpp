#include "refine/adam.h"

#include <cmath>

namespace ii {

namespace {
constexpr double kBeta1 = 0.9, kBeta2 = 0.999, kEps = 1e-15;  // 3DGS's eps

torch::Tensor leaf(torch::Tensor t) { return t.detach().requires_grad_(true); }
}  // namespace

void RowAdam::add(torch::Tensor* parameter, double lr) {
  slots_.push_back({parameter, torch::zeros_like(*parameter), torch::zeros_like(*parameter), lr});
}

void RowAdam::step() {
  torch::NoGradGuard no_grad;
  ++steps_;
  const double correction1 = 1 - std::pow(kBeta1, steps_), correction2 = 1 - std::pow(kBeta2, steps_);
  for (Slot& s : slots_) {
    torch::Tensor& g = s.parameter->mutable_grad();
    if (!g.defined()) continue;
    s.m.mul_(kBeta1).add_(g, 1 - kBeta1);
    s.v.mul_(kBeta2).addcmul_(g, g, 1 - kBeta2);
    const torch::Tensor denominator = (s.v / correction2).sqrt_().add_(kEps);
    s.parameter->addcdiv_(s.m, denominator, -s.lr / correction1);
    g = torch::Tensor();
  }
}

void RowAdam::keep_rows(const torch::Tensor& keep) {
  torch::NoGradGuard no_grad;
  for (Slot& s : slots_) {
    *s.parameter = leaf(s.parameter->index({keep}));
    s.m = s.m.index({keep});
    s.v = s.v.index({keep});
  }
}

void RowAdam::append_rows(const std::vector<torch::Tensor>& rows) {
  torch::NoGradGuard no_grad;
  for (size_t i = 0; i < slots_.size(); ++i) {
    Slot& s = slots_[i];
    const torch::Tensor r = rows[i].to(s.parameter->options().requires_grad(false));
    *s.parameter = leaf(torch::cat({*s.parameter, r}));
    s.m = torch::cat({s.m, torch::zeros_like(r)});
    s.v = torch::cat({s.v, torch::zeros_like(r)});
  }
}

}  // namespace ii
