#include "fill/whole_object.h"

#include <algorithm>
#include <deque>
#include <vector>

#include "render/projection.h"

namespace ii {

namespace {

// A level surface faces up within this (cosine of about 25 degrees).
constexpr double kLevel = 0.9;
// Neighbours of like depth differ by less than this share of it (two balls touching, a vase's neck
// on its body: 3 % split them on the ring rooms).
constexpr double kDepthStep = 0.06;
// Fewer level pixels than this under the part: nothing it stands on is in view.
constexpr int64_t kMinSupport = 20;

// The pixels reached from `seed` through 4-neighbours that are `covered`, of like depth and higher
// than `above`; one flag per pixel.
std::vector<uint8_t> grown_above(const torch::Tensor& depth, const torch::Tensor& covered, const torch::Tensor& seed,
                                 const torch::Tensor& height, double above) {
  const int64_t h = depth.size(0), w = depth.size(1);
  const double* d = depth.data_ptr<double>();
  const double* ht = height.data_ptr<double>();
  const bool* ok = covered.data_ptr<bool>();
  const bool* start = seed.data_ptr<bool>();
  std::vector<uint8_t> in(static_cast<size_t>(h * w), 0);
  std::deque<int64_t> queue;
  for (int64_t i = 0; i < h * w; ++i)
    if (start[i]) in[static_cast<size_t>(i)] = 1, queue.push_back(i);
  while (!queue.empty()) {
    const int64_t i = queue.front();
    queue.pop_front();
    const int64_t y = i / w, x = i % w;
    const int64_t next[4] = {x > 0 ? i - 1 : -1, x + 1 < w ? i + 1 : -1, y > 0 ? i - w : -1, y + 1 < h ? i + w : -1};
    for (int64_t j : next) {
      if (j < 0 || in[static_cast<size_t>(j)] || !ok[j] || ht[j] <= above) continue;
      if (std::abs(d[j] - d[i]) > kDepthStep * d[i]) continue;
      in[static_cast<size_t>(j)] = 1;
      queue.push_back(j);
    }
  }
  return in;
}

}  // namespace

std::optional<ObjectAboveSupport> object_above_support(const Camera& camera, const torch::Tensor& depth_in,
                                                       const torch::Tensor& covered_in, const torch::Tensor& part_in,
                                                       const Eigen::Vector3d& up_in) {
  const int64_t h = depth_in.size(0), w = depth_in.size(1);
  const torch::Tensor depth = depth_in.to(torch::kCPU, torch::kFloat64).contiguous();
  const torch::Tensor covered = covered_in.to(torch::kCPU, torch::kBool).contiguous();
  const torch::Tensor part = part_in.to(torch::kCPU, torch::kBool).logical_and(covered).contiguous();
  const Eigen::Vector3d up = up_in.normalized();
  const torch::Tensor upt = torch::tensor({up.x(), up.y(), up.z()}, torch::kFloat64);
  // Each pixel's height along up, and whether its surface is level.
  const torch::Tensor v = torch::arange(h, torch::kFloat64).unsqueeze(1).expand({h, w}).reshape({-1});
  const torch::Tensor u = torch::arange(w, torch::kFloat64).unsqueeze(0).expand({h, w}).reshape({-1});
  const torch::Tensor height = (unproject(camera, v, u, depth.reshape({-1})) * upt).sum(1).reshape({h, w}).contiguous();
  const torch::Tensor level = (depth_normals(camera, depth) * upt).sum(2).gt(kLevel).logical_and(covered);

  const torch::Tensor part_heights = height.index({part});
  if (part_heights.numel() == 0) return std::nullopt;
  auto quantile = [](const torch::Tensor& t, double q) {  // the value at rank q (n - 1), rounded down
    return torch::quantile(t, q, c10::nullopt, false, "lower").item<double>();
  };
  const double low = quantile(part_heights, 0.02), extent = std::max(1e-9, quantile(part_heights, 0.98) - low);
  const double scale = depth.index({part}).median().item<double>();  // how far the part is
  // Near the part: its box grown by its size on every side.
  const torch::Tensor where = part.nonzero();
  const int64_t y0 = where.select(1, 0).min().item<int64_t>(), y1 = where.select(1, 0).max().item<int64_t>();
  const int64_t x0 = where.select(1, 1).min().item<int64_t>(), x1 = where.select(1, 1).max().item<int64_t>();
  const int64_t gy = y1 - y0 + 2, gx = x1 - x0 + 2;
  torch::Tensor near = torch::zeros({h, w}, torch::kBool);
  near.slice(0, std::max<int64_t>(0, y0 - gy), std::min(h, y1 + gy + 1))
      .slice(1, std::max<int64_t>(0, x0 - gx), std::min(w, x1 + gx + 1))
      .fill_(true);
  // What it stands on: the highest level surface near the part and under its foot that shows at
  // least half as many pixels as the part (a level top of the object itself, under the part,
  // shows fewer), its heights in bins of 3 % of the part's distance (a trained floor's surface is
  // that rough on the ring rooms: at 1 % no bin held enough).
  const torch::Tensor under = level.logical_and(near).logical_and(part.logical_not())
                                  .logical_and(height.le(low + 0.1 * extent));
  const torch::Tensor levels = height.index({under});
  const int64_t needed = std::max<int64_t>(kMinSupport, part_heights.numel() / 2);
  if (levels.numel() < needed) return std::nullopt;
  const double bin = 0.03 * scale;
  const torch::Tensor bins = torch::floor(levels / bin).to(torch::kInt64);
  const int64_t first = bins.min().item<int64_t>();
  const torch::Tensor counts = torch::bincount(bins - first);
  const torch::Tensor neighbourhood =  // each bin with its two neighbours: a level surface spans a few
      counts + torch::cat({counts.slice(0, 1), torch::zeros({1}, counts.options())}) +
      torch::cat({torch::zeros({1}, counts.options()), counts.slice(0, 0, -1)});
  const torch::Tensor big = neighbourhood.ge(needed).nonzero();
  if (big.numel() == 0) return std::nullopt;
  const int64_t top = big.max().item<int64_t>();
  const double floor_height = levels.index({(bins - first - top).abs().le(1)}).median().item<double>();
  const double above = floor_height + 0.5 * bin;

  // Grown from the part over neighbours of like depth above the surface.
  const torch::Tensor part_depths = depth.index({part});
  const double front = torch::quantile(part_depths, 0.1).item<double>();  // linear, as measured
  const double back = torch::quantile(part_depths, 0.9).item<double>();
  const double width = std::max({static_cast<double>(x1 - x0) * scale / camera.K.fx,
                                 static_cast<double>(y1 - y0) * scale / camera.K.fy, back - front, extent});
  const std::vector<uint8_t> in = grown_above(depth, covered, part, height, above);
  const int64_t count = std::count(in.begin(), in.end(), uint8_t{1});
  if (2 * count > covered.sum().item<int64_t>()) return std::nullopt;
  ObjectAboveSupport out;
  out.mask = Image(static_cast<int>(w), static_cast<int>(h), 1);
  for (int64_t i = 0; i < h * w; ++i) out.mask.pixels[static_cast<size_t>(i)] = in[static_cast<size_t>(i)] ? 1.f : 0.f;
  out.up = up;
  out.above = above;
  out.nearest = front - width;
  out.farthest = back + width;
  return out;
}

}  // namespace ii
