#include "tensor/window_max.h"

#include <limits>
#include <vector>

#include "common/error.h"
#include "common/parallel.h"

namespace ii {

WindowMax window_max_with_index(const torch::Tensor& x, int64_t radius) {
  if (x.dim() != 2) fail("window max: expected an (H, W) tensor, got {} dimensions", x.dim());
  if (radius < 0) fail("window max: the radius must not be negative (got {})", radius);
  const int64_t H = x.size(0), W = x.size(1), side = 2 * radius + 1;
  if (!x.device().is_cpu() || x.scalar_type() != torch::kFloat32) {
    const auto [value, index] =
        torch::max_pool2d_with_indices(x.view({1, 1, H, W}), {side, side}, {1, 1}, {radius, radius});
    return {value.view({H, W}), index.view({H, W})};
  }
  const torch::Tensor in = x.contiguous();
  const float* v = in.data_ptr<float>();
  // Along each row: the row's largest within the window, and its column (strictly larger
  // replaces, so the leftmost of equals stays).
  std::vector<float> row_value(static_cast<size_t>(H * W));
  std::vector<int64_t> row_column(static_cast<size_t>(H * W));
  const int threads = thread_plan().cores;
  parallel_range(H, 16, threads, [&](int64_t y0, int64_t y1) {
    for (int64_t y = y0; y < y1; ++y)
      for (int64_t c = 0; c < W; ++c) {
        float best = -std::numeric_limits<float>::infinity();
        int64_t at = std::max<int64_t>(0, c - radius);
        for (int64_t k = std::max<int64_t>(0, c - radius); k <= std::min(W - 1, c + radius); ++k)
          if (v[y * W + k] > best) {
            best = v[y * W + k];
            at = k;
          }
        row_value[static_cast<size_t>(y * W + c)] = best;
        row_column[static_cast<size_t>(y * W + c)] = at;
      }
  });
  // Along each column of those: the topmost of equals stays, so of the square's equals the first
  // in row-major order wins, as in LibTorch.
  torch::Tensor value = torch::empty({H, W}, torch::kFloat32);
  torch::Tensor index = torch::empty({H, W}, torch::kInt64);
  float* out_value = value.data_ptr<float>();
  int64_t* out_index = index.data_ptr<int64_t>();
  parallel_range(H, 16, threads, [&](int64_t y0, int64_t y1) {
    for (int64_t y = y0; y < y1; ++y)
      for (int64_t c = 0; c < W; ++c) {
        float best = -std::numeric_limits<float>::infinity();
        int64_t at = std::max<int64_t>(0, y - radius) * W + std::max<int64_t>(0, c - radius);
        for (int64_t r = std::max<int64_t>(0, y - radius); r <= std::min(H - 1, y + radius); ++r)
          if (row_value[static_cast<size_t>(r * W + c)] > best) {
            best = row_value[static_cast<size_t>(r * W + c)];
            at = r * W + row_column[static_cast<size_t>(r * W + c)];
          }
        out_value[y * W + c] = best;
        out_index[y * W + c] = at;
      }
  });
  return {value, index};
}

}  // namespace ii
