#pragma once
// Learning rate per iteration (spec §6.5): a linear warm-up whose first and last iterations
// sit exactly on its endpoints, then a cosine decay from the peak to the final rate over the
// remaining iterations. The official run: 200 warm-up iterations from 1e-10 to 8e-5, cosine
// to 1e-6.
#include <cstdint>

namespace ii {

struct LrSchedule {
  double start_lr = 1e-10;  // first warm-up iteration
  double peak_lr = 8e-5;    // last warm-up iteration and start of the cosine
  double final_lr = 1e-6;   // the cosine's end (reached at total_steps)
  int64_t warmup_steps = 200;
  int64_t total_steps = 0;  // warm-up included

  // Iteration k (0-based). Warm-up, k < W: start + (peak − start)·k/(W − 1).
  // Then j = k − W: final + ½(peak − final)(1 + cos(π j / (total − W))); k ≥ total keeps final.
  double at(int64_t step) const;
  // Rejects negative sizes, a warm-up not shorter than the run, and rates that are not
  // positive and finite; the message names the option.
  void validate() const;
};

}  // namespace ii
