#include "geometry/flying_pixels.h"

#include <limits>
#include <utility>
#include <vector>

#include "common/error.h"

namespace ii {

using torch::indexing::Slice;

void check_flying_pixel_options(const FlyingPixelOptions& o) {
  if (!(o.jump > 0) || !(o.apart >= 0) || !(o.bend >= 0) || o.reach < 1 || o.reach > 64)
    fail("flying pixels: jump must be > 0, apart and bend >= 0, reach 1-64 (got {}, {}, {}, {})", o.jump, o.apart,
         o.bend, o.reach);
}

torch::Tensor flying_pixels(const torch::Tensor& depth_in, const FlyingPixelOptions& o) {
  check_flying_pixel_options(o);
  if (depth_in.dim() != 2) fail("flying pixels: the depth map must be (H, W), got {} dimensions", depth_in.dim());
  const torch::Tensor depth = depth_in.to(torch::kCPU, torch::kFloat32);
  const int64_t h = depth.size(0), w = depth.size(1);
  const torch::Tensor d = torch::where(depth.isfinite().logical_and(depth.gt(0)), depth, torch::zeros_like(depth));
  // Edge pixels repeat outward, so the picture's border has no edge across it.
  const torch::Tensor padded = torch::replication_pad2d(d.view({1, 1, h, w}), {1, 1, 1, 1})[0][0];
  auto neighbour = [&](int64_t dy, int64_t dx) {
    return padded.index({Slice(1 + dy, 1 + dy + h), Slice(1 + dx, 1 + dx + w)});
  };
  auto log_of = [](const torch::Tensor& x) { return x.clamp_min(1e-30).log(); };
  const torch::Tensor log_d = log_of(d);
  torch::Tensor flying = torch::zeros({h, w}, torch::kBool);
  for (const auto& [dy, dx] : std::vector<std::pair<int64_t, int64_t>>{{0, 1}, {1, 0}, {1, 1}, {1, -1}}) {
    const torch::Tensor a = neighbour(dy, dx), b = neighbour(-dy, -dx);
    const torch::Tensor log_a = log_of(a), log_b = log_of(b);
    const torch::Tensor known = d.gt(0).logical_and(a.gt(0)).logical_and(b.gt(0));
    const torch::Tensor edge = (log_a - log_b).abs().gt(o.jump);
    const torch::Tensor between = ((log_d - log_a) * (log_d - log_b)).lt(0);
    const torch::Tensor apart = torch::minimum((log_d - log_a).abs(), (log_d - log_b).abs()).gt(o.apart);
    const torch::Tensor bent =
        (d * (a.clamp_min(1e-30).reciprocal() + b.clamp_min(1e-30).reciprocal()) * 0.5 - 1).abs().gt(o.bend);
    flying |= known & edge & between & apart & bent;
  }
  return flying;
}

FarSide flying_pixels_to_far_side(const torch::Tensor& depth_in, const FlyingPixelOptions& o) {
  const torch::Tensor depth = depth_in.to(torch::kCPU, torch::kFloat32);
  const int64_t h = depth.size(0), w = depth.size(1);
  FarSide far;
  far.depth = depth;
  far.from = torch::arange(h * w, torch::kInt64).view({h, w});
  const torch::Tensor flying = flying_pixels(depth, o);
  far.moved = torch::zeros({h, w}, torch::kBool);
  if (!flying.any().item<bool>()) return far;
  const torch::Tensor sure = depth.isfinite().logical_and(depth.gt(0)).logical_and(flying.logical_not());
  const torch::Tensor candidates =
      torch::where(sure, depth, torch::full_like(depth, -std::numeric_limits<float>::infinity()));
  const int64_t k = 2 * o.reach + 1;
  const auto [farthest, at] =
      torch::max_pool2d_with_indices(candidates.view({1, 1, h, w}), {k, k}, {1, 1}, {o.reach, o.reach});
  const torch::Tensor found = farthest[0][0].isfinite();
  // Where no sure pixel is within reach the depth is left unknown.
  far.moved = flying.logical_and(found);
  far.depth = torch::where(far.moved, farthest[0][0], torch::where(flying, torch::zeros_like(depth), depth));
  far.from = torch::where(far.moved, at[0][0], far.from);
  return far;
}

torch::Tensor far_side_colours(const torch::Tensor& colour, const FarSide& far) {
  const int64_t h = far.from.size(0), w = far.from.size(1);
  if (colour.dim() != 3 || colour.size(1) != h || colour.size(2) != w)
    fail("flying pixels: the colours must be (C, {}, {})", h, w);
  return colour.reshape({colour.size(0), h * w}).index_select(1, far.from.flatten()).view({colour.size(0), h, w});
}

}  // namespace ii
