#include "geometry/behind_edges.h"

#include <algorithm>
#include <cmath>

#include "common/error.h"
#include "geometry/visibility.h"
#include "tensor/window_max.h"

namespace ii {

int64_t behind_edges_pixels(int64_t height, const BehindEdgesOptions& options) {
  if (!(options.fraction >= 0 && options.fraction <= 1))
    fail("behind edges: the fraction of the height must be between 0 and 1 (got {})", options.fraction);
  if (!(options.jump > 0 && options.jump <= 10))
    fail("behind edges: the depth jump must be above 0 and at most 10 (got {})", options.jump);
  return static_cast<int64_t>(std::llround(options.fraction * static_cast<double>(height)));
}

BehindEdgesOptions behind_edges_for(const BehindEdgesOptions& options, bool depth_maps) {
  if (!(options.depth_map_factor >= 1 && options.depth_map_factor <= 16))
    fail("behind edges: the depth maps' factor must be between 1 and 16 (got {})", options.depth_map_factor);
  BehindEdgesOptions out = options;
  if (depth_maps) out.fraction = std::min(1.0, options.fraction * options.depth_map_factor);
  return out;
}

namespace {

// (H, W) -> (1, 1, H, W) pooled over a k x k window, the same size.
torch::Tensor window_max(const torch::Tensor& x, int64_t k) {
  return torch::max_pool2d(x.unsqueeze(0).unsqueeze(0), {k, k}, {1, 1}, {k / 2, k / 2}).squeeze(0).squeeze(0);
}
torch::Tensor window_min(const torch::Tensor& x, int64_t k) { return -window_max(-x, k); }

// The far side of the depth edges of `depth` (H, W), two pixels from the edge: a nearer pixel
// within two pixels but none adjacent (the adjacent ones blend both sides in a photo), and no
// farther one adjacent (a blend of both sides has one).
torch::Tensor far_side_of_edges(const torch::Tensor& depth, double jump) {
  const torch::Tensor log_depth = depth.clamp_min(1e-6).log();
  const double step = std::log1p(jump);
  return (log_depth - window_min(log_depth, 5))
      .gt(step)
      .logical_and((log_depth - window_min(log_depth, 3)).le(step))
      .logical_and((window_max(log_depth, 3) - log_depth).lt(step / 3));
}

}  // namespace

GaussianSet gaussians_behind_edges(const GaussianMaps& maps, const ModelInput& input,
                                   const std::vector<PreparedView>& views, const BehindEdgesOptions& options) {
  if (!maps.depth.defined() || maps.depth.dim() != 5 || maps.depth.size(0) != 1)
    fail("behind edges: expected maps of shape (1, V, C, H, W)");
  const int64_t V = maps.depth.size(1), H = maps.depth.size(3), W = maps.depth.size(4);
  const int64_t reach = behind_edges_pixels(H, options);
  if (reach == 0) return {};
  torch::NoGradGuard no_grad;
  const std::vector<SeenDepth> seen = seen_depths(maps, views, input.view_cameras);
  GaussianSet all;
  for (int64_t v = 0; v < V; ++v) {
    const torch::Tensor& depth = seen[static_cast<size_t>(v)].depth;
    const torch::Tensor& usable = seen[static_cast<size_t>(v)].usable;
    // Each pixel's farthest far-side pixel within `reach`, and where it lies deeper than the pixel.
    const torch::Tensor sources =
        torch::where(usable.logical_and(far_side_of_edges(depth, options.jump)), depth, torch::zeros_like(depth));
    const WindowMax nearby = window_max_with_index(sources, reach);
    const torch::Tensor &far = nearby.value, &from = nearby.index;
    const torch::Tensor far_depth = far.view({H * W});
    const torch::Tensor under =
        far_depth.gt(depth.view({H * W}) * (1 + options.jump)).logical_and(usable.view({H * W}));
    const torch::Tensor at = under.nonzero().squeeze(1);
    if (at.numel() == 0) continue;
    const torch::Tensor source = from.view({H * W}).index_select(0, at);
    auto of_source = [&](const torch::Tensor& map) {  // (1, V, C, H, W) -> (n, C)
      return map[0][v].reshape({map.size(2), H * W}).index_select(1, source).t();
    };
    GaussianSet g;
    g.sh_degree = -1;
    g.quats = of_source(maps.rotation);
    g.opacities = of_source(maps.opacity).reshape({-1});
    g.colors = of_source(maps.rgb);
    g.scales = of_source(maps.scale);
    // On the near pixel's own ray (z-depth directions) at the far side's depth.
    const auto on_ray = [&](const torch::Tensor& t) {
      return t[v].reshape({H * W, 3}).index_select(0, at).to(torch::kFloat32);
    };
    g.means = (on_ray(input.rays_o) + far_depth.index_select(0, at).view({-1, 1}) * on_ray(input.rays_d_un))
                  .to(maps.xyz.scalar_type());
    all = all.size() == 0 ? g : joined(all, g);
  }
  return all;
}

nlohmann::json describe_behind_edges(const BehindEdgesOptions& options, int64_t height, int64_t gaussians,
                                     int64_t dropped) {
  return {{"fraction", options.fraction},
          {"pixels", behind_edges_pixels(height, options)},
          {"jump", options.jump},
          {"gaussians", gaussians},
          {"dropped", dropped}};
}

}  // namespace ii
