#pragma once
// Adam over a few tensors whose rows may be removed or appended between steps (densification
// changes the number of Gaussians; LibTorch's optimizers key their state by tensor and cannot
// follow that). The moments of appended rows start at zero, as in 3DGS, and their bias
// correction counts their own steps: with the optimiser's count (3DGS's way) a new row's first
// hundred steps are 3-6 times the rate (m / sqrt(v) of zeroed moments), harmless at 3DGS's
// position rate, but at refinement's 300 times that rate it throws new Gaussians away.
#include <vector>

#include "common/torch.h"

namespace ii {

class RowAdam {
 public:
  // A leaf tensor (requires_grad) optimised at rate `lr`; rows are its first dimension.
  void add(torch::Tensor* parameter, double lr);
  void set_lr(size_t slot, double lr) { slots_[slot].lr = lr; }
  // One Adam step for every parameter that has a gradient; the gradients are then cleared.
  void step();
  // Keep the rows where `keep` (bool, N) is true, in every parameter and its moments.
  void keep_rows(const torch::Tensor& keep);
  // Append rows, one tensor per parameter in the order added (moments zero).
  void append_rows(const std::vector<torch::Tensor>& rows);
  // Forget one parameter's moments, as if its optimisation started now (after its values were
  // reset: 3DGS's opacity reset).
  void restart(size_t slot);

 private:
  struct Slot {
    torch::Tensor* parameter;
    torch::Tensor m, v;
    torch::Tensor age;  // float (N): steps each row has taken in this slot
    double lr;
  };
  std::vector<Slot> slots_;
};

}  // namespace ii
