#include "geometry/continued_depth.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "common/error.h"

namespace ii {

namespace {

enum : uint8_t { kLeftOut = 0, kKnown = 1, kUnknown = 2 };

// Inverse depth on a pixel grid, each pixel known, unknown or left out.
struct Grid {
  int width = 0, height = 0;
  std::vector<float> value;
  std::vector<uint8_t> state;
};

// Half the size: a pixel is known (their mean) when any of its four is, else unknown when any is.
Grid coarser(const Grid& g) {
  Grid c;
  c.width = (g.width + 1) / 2;
  c.height = (g.height + 1) / 2;
  c.value.assign(static_cast<size_t>(c.width) * c.height, 0.f);
  c.state.assign(c.value.size(), kLeftOut);
  for (int y = 0; y < c.height; ++y)
    for (int x = 0; x < c.width; ++x) {
      float sum = 0;
      int known = 0;
      bool unknown = false;
      for (int fy = 2 * y; fy < std::min(2 * y + 2, g.height); ++fy)
        for (int fx = 2 * x; fx < std::min(2 * x + 2, g.width); ++fx) {
          const size_t i = static_cast<size_t>(fy) * g.width + fx;
          if (g.state[i] == kKnown) sum += g.value[i], ++known;
          unknown = unknown || g.state[i] == kUnknown;
        }
      const size_t i = static_cast<size_t>(y) * c.width + x;
      if (known > 0) {
        c.state[i] = kKnown;
        c.value[i] = sum / static_cast<float>(known);
      } else if (unknown) {
        c.state[i] = kUnknown;
      }
    }
  return c;
}

// Gauss-Seidel with over-relaxation over the unknown pixels: each the mean of its neighbours
// that are not left out.
void relax(Grid& g, const std::vector<size_t>& unknown, int iterations) {
  constexpr float kOmega = 1.6f;
  const auto w = static_cast<size_t>(g.width);
  for (int it = 0; it < iterations; ++it)
    for (const size_t i : unknown) {
      const size_t x = i % w;
      float sum = 0;
      int n = 0;
      auto add = [&](size_t j) {
        if (g.state[j] != kLeftOut) sum += g.value[j], ++n;
      };
      if (x > 0) add(i - 1);
      if (x + 1 < w) add(i + 1);
      if (i >= w) add(i - w);
      if (i + w < g.value.size()) add(i + w);
      if (n > 0) g.value[i] += kOmega * (sum / static_cast<float>(n) - g.value[i]);
    }
}

// Solves the unknown pixels, starting each level from the coarser one's solution; false when
// there is nothing known to start from.
bool solve(Grid& g) {
  std::vector<size_t> unknown;
  double known_sum = 0;
  int64_t known = 0;
  for (size_t i = 0; i < g.state.size(); ++i) {
    if (g.state[i] == kUnknown) unknown.push_back(i);
    if (g.state[i] == kKnown) known_sum += g.value[i], ++known;
  }
  if (unknown.empty()) return true;
  if (known == 0) return false;
  if (g.width > 8 && g.height > 8) {
    Grid c = coarser(g);
    if (!solve(c)) return false;
    for (const size_t i : unknown) {
      const size_t x = i % static_cast<size_t>(g.width), y = i / static_cast<size_t>(g.width);
      g.value[i] = c.value[(y / 2) * static_cast<size_t>(c.width) + x / 2];
    }
    relax(g, unknown, 30);
  } else {
    for (const size_t i : unknown) g.value[i] = static_cast<float>(known_sum / static_cast<double>(known));
    relax(g, unknown, 200);
  }
  return true;
}

}  // namespace

std::optional<torch::Tensor> complete_depth(const torch::Tensor& depth, const torch::Tensor& known,
                                            const torch::Tensor& unknown) {
  if (depth.dim() != 2 || known.sizes() != depth.sizes() || unknown.sizes() != depth.sizes())
    fail("complete_depth: depth, known and unknown must be (H, W) alike");
  const torch::Tensor d = depth.to(torch::kCPU, torch::kFloat32).contiguous();
  const torch::Tensor k = known.to(torch::kCPU).logical_and(d > 0).logical_and(unknown.to(torch::kCPU).logical_not());
  const torch::Tensor u = unknown.to(torch::kCPU, torch::kBool).contiguous();
  Grid g;
  g.height = static_cast<int>(d.size(0));
  g.width = static_cast<int>(d.size(1));
  g.value.assign(static_cast<size_t>(d.numel()), 0.f);
  g.state.assign(g.value.size(), kLeftOut);
  const float* dp = d.data_ptr<float>();
  const torch::Tensor kc = k.contiguous();
  const bool* kp = kc.data_ptr<bool>();
  const bool* up = u.data_ptr<bool>();
  for (size_t i = 0; i < g.value.size(); ++i) {
    if (up[i]) {
      g.state[i] = kUnknown;
    } else if (kp[i]) {
      g.state[i] = kKnown;
      g.value[i] = 1.f / dp[i];
    }
  }
  if (!solve(g)) return std::nullopt;
  torch::Tensor out = d.clone();
  float* op = out.data_ptr<float>();
  for (size_t i = 0; i < g.value.size(); ++i)
    if (g.state[i] == kUnknown) op[i] = g.value[i] > 0 ? 1.f / g.value[i] : 0.f;
  return out;
}

}  // namespace ii
