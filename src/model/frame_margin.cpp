#include "model/frame_margin.h"

#include <cmath>

#include "common/error.h"
#include "model/floaters.h"

namespace ii {

int64_t frame_margin_pixels(int64_t height, const FrameMarginOptions& options) {
  if (!(options.fraction >= 0 && options.fraction <= 1))
    fail("frame margin: the fraction of the height must be between 0 and 1 (got {})", options.fraction);
  return static_cast<int64_t>(std::llround(options.fraction * static_cast<double>(height)));
}

GaussianSet gaussians_beyond_frame(const GaussianMaps& maps, const ModelInput& input,
                                   const FrameMarginOptions& options) {
  if (!maps.depth.defined() || maps.depth.dim() != 5 || maps.depth.size(0) != 1)
    fail("frame margin: expected maps of shape (1, V, C, H, W)");
  const int64_t V = maps.depth.size(1), H = maps.depth.size(3), W = maps.depth.size(4);
  const int64_t margin = frame_margin_pixels(H, options);
  if (margin == 0 || H < 2 || W < 2) return {};
  torch::NoGradGuard no_grad;
  const torch::Device device = maps.depth.device();
  const auto i64 = torch::TensorOptions().dtype(torch::kInt64).device(device);
  const auto f32 = torch::TensorOptions().dtype(torch::kFloat32).device(device);

  // The pixels past the frame, row by row: (u, v) with u in [-margin, W + margin), v likewise.
  const torch::Tensor u_axis = torch::arange(-margin, W + margin, i64);
  const torch::Tensor v_axis = torch::arange(-margin, H + margin, i64);
  const torch::Tensor u_all = u_axis.view({1, -1}).expand({v_axis.size(0), u_axis.size(0)}).reshape({-1});
  const torch::Tensor v_all = v_axis.view({-1, 1}).expand({v_axis.size(0), u_axis.size(0)}).reshape({-1});
  const torch::Tensor outside = (u_all < 0) | (u_all >= W) | (v_all < 0) | (v_all >= H);
  const torch::Tensor u = u_all.masked_select(outside), v = v_all.masked_select(outside);
  const int64_t n = u.size(0);

  // Each new pixel takes its nearest border pixel's attributes (the same pixels in every view).
  const torch::Tensor border = v.clamp(0, H - 1) * W + u.clamp(0, W - 1);
  auto at_border = [&](const torch::Tensor& map) {  // (1, V, C, H, W) -> (V * n, C)
    const int64_t C = map.size(2);
    return map[0].reshape({V, C, H * W}).index_select(2, border).permute({0, 2, 1}).reshape({V * n, C});
  };
  GaussianSet g;
  g.sh_degree = -1;
  g.quats = at_border(maps.rotation);
  g.opacities = at_border(maps.opacity).reshape({-1});
  g.colors = at_border(maps.rgb);
  g.scales = at_border(maps.scale);
  const torch::Tensor depth = at_border(maps.depth).to(torch::kFloat32).view({V, n, 1});

  // Rays of a pinhole camera are affine in the pixel index: continue them past the frame from
  // the first pixel's ray and its steps along a row and down a column.
  const torch::Tensor& rays = input.rays_d_un;  // (V, H, W, 3), z-depth directions
  const torch::Tensor first = rays.select(1, 0).select(1, 0).to(f32).view({V, 1, 3});
  const torch::Tensor along_row = rays.select(1, 0).select(1, 1).to(f32).view({V, 1, 3}) - first;
  const torch::Tensor down_column = rays.select(1, 1).select(1, 0).to(f32).view({V, 1, 3}) - first;
  const torch::Tensor direction = first + u.to(f32).view({1, n, 1}) * along_row + v.to(f32).view({1, n, 1}) * down_column;
  const torch::Tensor origin = input.rays_o.select(1, 0).select(1, 0).to(f32).view({V, 1, 3});
  g.means = (origin + depth * direction).reshape({V * n, 3}).to(maps.xyz.scalar_type());
  return g;
}

GaussianSet without_seen_through(const GaussianSet& margin, const GaussianMaps& maps,
                                 const std::vector<PreparedView>& views, const std::vector<Camera>& cameras) {
  if (margin.size() == 0) return margin;
  torch::NoGradGuard no_grad;
  const torch::Tensor through =
      seen_through(margin.means.to(torch::kFloat32), view_depths(maps, views), cameras, /*tolerance=*/0);
  return select_rows(margin, through.logical_not());
}

nlohmann::json describe_frame_margin(const FrameMarginOptions& options, int64_t height, int64_t gaussians,
                                     int64_t dropped) {
  return {{"fraction", options.fraction},
          {"pixels", frame_margin_pixels(height, options)},
          {"gaussians", gaussians},
          {"drop_seen_through", options.drop_seen_through},
          {"dropped", dropped}};
}

}  // namespace ii
