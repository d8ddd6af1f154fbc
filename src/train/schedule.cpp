#include "train/schedule.h"

#include <cmath>

#include "common/error.h"

namespace ii {

double LrSchedule::at(int64_t step) const {
  if (step < warmup_steps) {
    if (warmup_steps == 1) return peak_lr;
    return start_lr + (peak_lr - start_lr) * static_cast<double>(step) / static_cast<double>(warmup_steps - 1);
  }
  const int64_t decay_steps = total_steps - warmup_steps;
  if (decay_steps <= 0 || step >= total_steps) return final_lr;
  const double progress = static_cast<double>(step - warmup_steps) / static_cast<double>(decay_steps);
  return final_lr + 0.5 * (peak_lr - final_lr) * (1.0 + std::cos(M_PI * progress));
}

void LrSchedule::validate() const {
  if (total_steps < 1) fail("--steps must be at least 1, got {}", total_steps);
  if (warmup_steps < 0 || warmup_steps >= total_steps)
    fail("--warmup must be between 0 and --steps - 1 ({}), got {}", total_steps - 1, warmup_steps);
  for (auto [name, value] : {std::pair{"--lr", peak_lr}, {"--lr-start", start_lr}, {"--lr-final", final_lr}})
    if (!(value > 0) || !std::isfinite(value)) fail("{} must be a positive number, got {}", name, value);
}

}  // namespace ii
