#include "geometry/frame_margin.h"

#include <algorithm>
#include <cmath>

#include "common/error.h"
#include "geometry/visibility.h"

namespace ii {

int64_t frame_margin_pixels(int64_t height, const FrameMarginOptions& options) {
  if (!(options.fraction >= 0 && options.fraction <= 1))
    fail("frame margin: the fraction of the height must be between 0 and 1 (got {})", options.fraction);
  return static_cast<int64_t>(std::llround(options.fraction * static_cast<double>(height)));
}

int64_t frame_margin_outer_pixels(int64_t height, const FrameMarginOptions& options) {
  if (!(options.outer_fraction >= 0 && options.outer_fraction <= 1))
    fail("frame margin: the outer fraction of the height must be between 0 and 1 (got {})", options.outer_fraction);
  if (options.outer_stride < 1 || options.outer_stride > 16)
    fail("frame margin: the outer stride must be between 1 and 16 pixels (got {})", options.outer_stride);
  const int64_t inner = frame_margin_pixels(height, options);
  if (inner == 0) return 0;  // no dense band, no margin
  return std::max(inner, static_cast<int64_t>(std::llround(options.outer_fraction * static_cast<double>(height))));
}

namespace {

// The margin's pixels of one view, the same in every view: the dense band's pixels, then past
// it one pixel per outer_stride x outer_stride block (its top-left corner).
struct MarginPixels {
  torch::Tensor u, v;   // (n,) int64, the pixel (block corner) past the frame
  torch::Tensor block;  // (n,) int64, 1 for the dense band, outer_stride past it
};

MarginPixels margin_pixels(int64_t H, int64_t W, const FrameMarginOptions& options, const torch::Device& device) {
  const int64_t inner = frame_margin_pixels(H, options), outer = frame_margin_outer_pixels(H, options);
  const auto i64 = torch::TensorOptions().dtype(torch::kInt64).device(device);
  const torch::Tensor u_axis = torch::arange(-outer, W + outer, i64);
  const torch::Tensor v_axis = torch::arange(-outer, H + outer, i64);
  const torch::Tensor u_all = u_axis.view({1, -1}).expand({v_axis.size(0), u_axis.size(0)}).reshape({-1});
  const torch::Tensor v_all = v_axis.view({-1, 1}).expand({v_axis.size(0), u_axis.size(0)}).reshape({-1});
  // How far past the frame (0 inside): the larger of the column's and the row's overshoot.
  const torch::Tensor past = torch::max(torch::max(-u_all, u_all - (W - 1)), torch::max(-v_all, v_all - (H - 1)));
  const int64_t stride = options.outer_stride;
  const torch::Tensor corner = ((u_all + outer) % stride == 0) & ((v_all + outer) % stride == 0);
  const torch::Tensor dense = (past > 0) & (past <= inner);
  const torch::Tensor sparse = (past > inner) & corner;
  const torch::Tensor keep = dense | sparse;
  return {u_all.masked_select(keep), v_all.masked_select(keep),
          torch::where(sparse.masked_select(keep), torch::full({}, stride, i64), torch::ones({}, i64))};
}

}  // namespace

GaussianSet gaussians_beyond_frame(const GaussianMaps& maps, const ModelInput& input,
                                   const FrameMarginOptions& options) {
  if (!maps.depth.defined() || maps.depth.dim() != 5 || maps.depth.size(0) != 1)
    fail("frame margin: expected maps of shape (1, V, C, H, W)");
  const int64_t V = maps.depth.size(1), H = maps.depth.size(3), W = maps.depth.size(4);
  if (frame_margin_outer_pixels(H, options) == 0 || H < 2 || W < 2) return {};
  torch::NoGradGuard no_grad;
  const torch::Device device = maps.depth.device();
  const auto f32 = torch::TensorOptions().dtype(torch::kFloat32).device(device);
  const MarginPixels pixels = margin_pixels(H, W, options, device);
  const torch::Tensor& u = pixels.u;
  const torch::Tensor& v = pixels.v;
  const int64_t n = u.size(0);

  // Each new pixel takes its nearest border pixel's attributes (the same pixels in every view).
  const torch::Tensor border = v.clamp(0, H - 1) * W + u.clamp(0, W - 1);
  auto at_border = [&](const torch::Tensor& map) {  // (1, V, C, H, W) -> (V * n, C)
    const int64_t C = map.size(2);
    return map[0].reshape({V, C, H * W}).index_select(2, border).permute({0, 2, 1}).reshape({V * n, C});
  };
  // A block's one Gaussian is as wide as the block and as opaque as the block's pixels' Gaussians
  // laid over each other.
  const torch::Tensor block = pixels.block.to(f32).view({1, n, 1}).expand({V, n, 1}).reshape({V * n, 1});
  GaussianSet g;
  g.sh_degree = -1;
  g.quats = at_border(maps.rotation);
  const torch::Tensor opacity = at_border(maps.opacity).to(torch::kFloat32);
  g.opacities = (1 - (1 - opacity).pow(block * block)).reshape({-1}).to(maps.opacity.scalar_type());
  g.colors = at_border(maps.rgb);
  g.scales = (at_border(maps.scale).to(torch::kFloat32) * block).to(maps.scale.scalar_type());
  const torch::Tensor depth = at_border(maps.depth).to(torch::kFloat32).view({V, n, 1});

  // Rays of a pinhole camera are affine in the pixel index: continue them past the frame from
  // the first pixel's ray and its steps along a row and down a column, to the block's centre.
  const torch::Tensor& rays = input.rays_d_un;  // (V, H, W, 3), z-depth directions
  const torch::Tensor first = rays.select(1, 0).select(1, 0).to(f32).view({V, 1, 3});
  const torch::Tensor along_row = rays.select(1, 0).select(1, 1).to(f32).view({V, 1, 3}) - first;
  const torch::Tensor down_column = rays.select(1, 1).select(1, 0).to(f32).view({V, 1, 3}) - first;
  const torch::Tensor centre_offset = (pixels.block.to(f32) - 1) / 2;
  const torch::Tensor uc = (u.to(f32) + centre_offset).view({1, n, 1});
  const torch::Tensor vc = (v.to(f32) + centre_offset).view({1, n, 1});
  const torch::Tensor direction = first + uc * along_row + vc * down_column;
  const torch::Tensor origin = input.rays_o.select(1, 0).select(1, 0).to(f32).view({V, 1, 3});
  g.means = (origin + depth * direction).reshape({V * n, 3}).to(maps.xyz.scalar_type());
  return g;
}

GaussianSet without_seen_through(const GaussianSet& margin, const GaussianMaps& maps,
                                 const std::vector<PreparedView>& views, const std::vector<Camera>& cameras) {
  if (margin.size() == 0) return margin;
  torch::NoGradGuard no_grad;
  const torch::Tensor through =
      seen_through(margin.means.to(torch::kFloat32), seen_depths(maps, views, cameras), /*tolerance=*/0);
  return select_rows(margin, through.logical_not());
}

nlohmann::json describe_frame_margin(const FrameMarginOptions& options, int64_t height, int64_t gaussians,
                                     int64_t dropped) {
  return {{"fraction", options.fraction},
          {"pixels", frame_margin_pixels(height, options)},
          {"outer_fraction", options.outer_fraction},
          {"outer_pixels", frame_margin_outer_pixels(height, options)},
          {"outer_stride", options.outer_stride},
          {"gaussians", gaussians},
          {"drop_seen_through", options.drop_seen_through},
          {"dropped", dropped}};
}

}  // namespace ii
