#include "refine/adam.h"

#include <cmath>

namespace ii {

namespace {
constexpr double kBeta1 = 0.9, kBeta2 = 0.999, kEps = 1e-15;  // 3DGS's eps

torch::Tensor leaf(torch::Tensor t) { return t.detach().requires_grad_(true); }
}  // namespace

void RowAdam::add(torch::Tensor* parameter, double lr) {
  slots_.push_back({parameter, torch::zeros_like(*parameter), torch::zeros_like(*parameter),
                    torch::zeros({parameter->size(0)}, parameter->options().dtype(torch::kFloat32)), lr});
}

void RowAdam::step() {
  torch::NoGradGuard no_grad;
  for (Slot& s : slots_) {
    torch::Tensor& g = s.parameter->mutable_grad();
    if (!g.defined()) continue;
    s.age.add_(1);
    // Per row: 1 − β^age (age ≥ 1), shaped to broadcast over the parameter's other dimensions.
    const torch::Tensor correction1 = 1 - torch::pow(kBeta1, s.age), correction2 = 1 - torch::pow(kBeta2, s.age);
    std::vector<int64_t> shape(static_cast<size_t>(s.parameter->dim()), 1);
    shape[0] = -1;
    s.m.mul_(kBeta1).add_(g, 1 - kBeta1);
    s.v.mul_(kBeta2).addcmul_(g, g, 1 - kBeta2);
    const torch::Tensor denominator = (s.v / correction2.view(shape)).sqrt_().add_(kEps);
    s.parameter->addcdiv_(s.m / correction1.view(shape), denominator, -s.lr);
    g = torch::Tensor();
  }
}

void RowAdam::keep_rows(const torch::Tensor& keep) {
  torch::NoGradGuard no_grad;
  for (Slot& s : slots_) {
    *s.parameter = leaf(s.parameter->index({keep}));
    s.m = s.m.index({keep});
    s.v = s.v.index({keep});
    s.age = s.age.index({keep});
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
    s.age = torch::cat({s.age, torch::zeros({r.size(0)}, s.age.options())});
  }
}

void RowAdam::restart(size_t slot) {
  Slot& s = slots_.at(slot);
  s.m.zero_();
  s.v.zero_();
  s.age.zero_();
}

}  // namespace ii
