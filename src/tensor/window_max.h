#pragma once
// The largest value within a square window around each pixel, and where it is: what
// max_pool2d_with_indices answers at stride 1 with the window's half as padding, for the large
// windows the geometry uses (behind depth edges: 17 x 17 at 256 rows, 33 x 33 at 512). On the CPU
// in two passes of one window side each, along the rows and then the columns, instead of one pass
// over the whole square: 4 views at 256 rows 51-72 ms in LibTorch 1.13, a few here.
#include "common/torch.h"

namespace ii {

struct WindowMax {
  torch::Tensor value;  // (H, W), x's dtype
  torch::Tensor index;  // (H, W) int64: where that value is, as y * W + x
};

// `x` (H, W) of any floating dtype and device; `radius` >= 0 (the window's side 2 * radius + 1).
// Ties go to the first in row-major order, as in LibTorch, so the answers are LibTorch's exactly
// (x without NaN). Other than float32 on the CPU it is LibTorch's own pooling.
WindowMax window_max_with_index(const torch::Tensor& x, int64_t radius);

}  // namespace ii
