#include "geometry/region_surface.h"

#include <algorithm>
#include <cmath>

#include "common/cpu_features.h"
#include "common/error.h"
#include "common/parallel.h"
#include "geometry/flying_pixels.h"
#include "geometry/region_weights.h"
#include "model/scene_input.h"
#include "geometry/surface_splats.h"

namespace ii {

using torch::indexing::None;
using torch::indexing::Slice;

namespace {

// (H, W) -> (1, 1, H, W) float.
torch::Tensor as_map(const torch::Tensor& t) { return t.to(torch::kFloat32).view({1, 1, t.size(0), t.size(1)}); }

// `mask` (H, W bool) grown by a square of radius r: a row pass, then a column pass.
torch::Tensor grown(const torch::Tensor& mask, int64_t r) {
  if (r <= 0) return mask;
  const torch::Tensor rows = torch::max_pool2d(as_map(mask), {1, 2 * r + 1}, {1, 1}, {0, r});
  return torch::max_pool2d(rows, {2 * r + 1, 1}, {1, 1}, {r, 0})[0][0].gt(0.5);
}

// Pixel coordinates (N, 2: x, y) of flat indices into an image `width` wide.
torch::Tensor pixel_xy(const torch::Tensor& flat, int64_t width) {
  return torch::stack({torch::remainder(flat, width), torch::div(flat, width, "floor")}, 1).to(torch::kFloat32);
}

// The slope (d/dx, d/dy, each (H, W)) of the plane fitted by least squares to `q` (H, W) over a
// window of `known` pixels about each pixel, zero where it fits worse than `fit` of q or where
// under half the window is known: the local moments from box filters, a 2 x 2 solve per pixel.
std::pair<torch::Tensor, torch::Tensor> local_slopes(const torch::Tensor& q, const torch::Tensor& known, int64_t radius,
                                                     double fit) {
  const int64_t H = q.size(0), W = q.size(1), k = 2 * radius + 1;
  const torch::Tensor m = as_map(known);
  auto mean = [&](const torch::Tensor& t) {
    return torch::avg_pool2d(as_map(t) * m, {k, k}, {1, 1}, {radius, radius}, false, false)[0][0];
  };
  const torch::Tensor x = torch::arange(W, torch::kFloat32).view({1, W}).expand({H, W});
  const torch::Tensor y = torch::arange(H, torch::kFloat32).view({H, 1}).expand({H, W});
  const torch::Tensor share = mean(torch::ones_like(q));
  const torch::Tensor n = share.clamp_min(1e-9);
  const torch::Tensor mx = mean(x) / n, my = mean(y) / n, mq = mean(q) / n;
  const torch::Tensor cxx = mean(x * x) / n - mx * mx, cyy = mean(y * y) / n - my * my, cxy = mean(x * y) / n - mx * my;
  const torch::Tensor cxq = mean(x * q) / n - mx * mq, cyq = mean(y * q) / n - my * mq, cqq = mean(q * q) / n - mq * mq;
  const torch::Tensor det = (cxx * cyy - cxy * cxy).clamp_min(1e-9);
  const torch::Tensor dx = (cyy * cxq - cxy * cyq) / det, dy = (cxx * cyq - cxy * cxq) / det;
  const torch::Tensor residual = (cqq - dx * cxq - dy * cyq).clamp_min(0).sqrt();
  const torch::Tensor fits = share.gt(0.5).logical_and(residual.lt(fit * mq)).logical_and(known);
  return {torch::where(fits, dx, torch::zeros_like(dx)), torch::where(fits, dy, torch::zeros_like(dy))};
}

// The ring's pixels (flat indices): measured ones past the gap and within reach of the region, at
// most `ring_samples` of them, evenly spaced.
torch::Tensor ring_pixels(const torch::Tensor& region, const torch::Tensor& known, const RegionSurfaceOptions& o) {
  const int64_t reach = std::max<int64_t>(1, std::llround(o.reach * static_cast<double>(region.size(0))));
  const torch::Tensor ring =
      known.logical_and(grown(region, o.gap).logical_not()).logical_and(grown(region, o.gap + reach));
  torch::Tensor at = ring.flatten().nonzero().squeeze(1);
  if (at.numel() > o.ring_samples)
    at = at.index({Slice(None, None, (at.numel() + o.ring_samples - 1) / o.ring_samples)});
  return at;
}

// Each ring pixel's plane of inverse depth as (m, 3) coefficients of (1, x, y): its value, and
// with `slopes` its local slope (else flat).
torch::Tensor ring_planes(const torch::Tensor& inverse, const torch::Tensor& known, const torch::Tensor& ring_at,
                          const torch::Tensor& ring_xy, bool slopes, const RegionSurfaceOptions& o) {
  const torch::Tensor value = inverse.flatten().index_select(0, ring_at);
  torch::Tensor dx = torch::zeros_like(value), dy = torch::zeros_like(value);
  if (slopes) {
    const int64_t H = inverse.size(0);
    const int64_t radius = std::max<int64_t>(2, static_cast<int64_t>(o.slope_window * static_cast<double>(H) / 2));
    const auto [sx, sy] = local_slopes(inverse, known, radius, o.slope_fit);
    dx = sx.flatten().index_select(0, ring_at);
    dy = sy.flatten().index_select(0, ring_at);
  }
  // q + dx (x - x_ring) + dy (y - y_ring) is linear in (1, x, y).
  const torch::Tensor x = ring_xy.index({Slice(), 0}), y = ring_xy.index({Slice(), 1});
  return torch::stack({value - dx * x - dy * y, dx, dy}, 1);
}

}  // namespace

torch::Tensor depth_from_surroundings(const torch::Tensor& measured_in, const torch::Tensor& region_in,
                                      const torch::Tensor& colour_in, bool slopes, const RegionSurfaceOptions& o,
                                      int64_t* ring_used) {
  check_region_surface_options(o);
  const torch::Tensor measured = measured_in.to(torch::kCPU, torch::kFloat32).contiguous();
  const torch::Tensor region = region_in.to(torch::kCPU, torch::kBool);
  const int64_t H = measured.size(0), W = measured.size(1);
  if (region.sizes() != measured.sizes() || colour_in.dim() != 3 || colour_in.size(0) != 3 ||
      colour_in.size(1) != H || colour_in.size(2) != W)
    fail("region surface: the depth, region and colour must be one picture's size ({}x{})", W, H);
  if (ring_used) *ring_used = 0;
  torch::Tensor out = torch::zeros({H, W}, torch::kFloat32);
  const torch::Tensor inside = region.flatten().nonzero().squeeze(1);
  const torch::Tensor known = measured.gt(0).logical_and(measured.isfinite());
  const torch::Tensor ring_at = ring_pixels(region, known, o);
  if (inside.numel() == 0 || ring_at.numel() == 0) return out;
  if (ring_used) *ring_used = ring_at.numel();
  // Colours blurred over 5 x 5 pixels: a leaf's texture should not decide which surface a pixel is.
  const torch::Tensor blurred = torch::avg_pool2d(colour_in.to(torch::kCPU, torch::kFloat32).unsqueeze(0), {5, 5},
                                                  {1, 1}, {2, 2}, false, false);
  const torch::Tensor colour = blurred[0].reshape({3, H * W}).t();
  const torch::Tensor inverse = torch::where(known, measured.reciprocal(), torch::zeros_like(measured));
  const torch::Tensor ring_xy = pixel_xy(ring_at, W);
  const torch::Tensor planes = ring_planes(inverse, known, ring_at, ring_xy, slopes, o);  // (m, 3)
  // Held within a third and three times the ring's range (a slope continued too far).
  const torch::Tensor ring_inverse = inverse.flatten().index_select(0, ring_at);
  const double lowest = ring_inverse.min().item<double>() / 3, highest = ring_inverse.max().item<double>() * 3;
  // The weights are a softmax over the ring of -|a - b|^2, a and b a pixel's position and colour
  // each divided by its width (times sqrt 2): -|a|^2 is the same for every ring pixel, so the
  // logits are one product, 2 a.b - |b|^2.
  const double spatial = std::sqrt(2.0) * o.spatial * static_cast<double>(H), tint = std::sqrt(2.0) * o.colour;
  auto features = [&](const torch::Tensor& xy, const torch::Tensor& rgb) {
    return torch::cat({xy / spatial, rgb / tint}, 1);
  };
  const torch::Tensor ring_features = features(ring_xy, colour.index_select(0, ring_at));  // (m, 5)
  const torch::Tensor xy = pixel_xy(inside, W);
  const torch::Tensor c = ring_weighted_planes(features(xy, colour.index_select(0, inside)), ring_features, planes);
  const torch::Tensor here = c.index({Slice(), 0}) + c.index({Slice(), 1}) * xy.index({Slice(), 0}) +
                             c.index({Slice(), 2}) * xy.index({Slice(), 1});
  out.view({-1}).index_put_({inside}, here.clamp(lowest, highest).reciprocal());
  return out;
}

torch::Tensor ring_weighted_planes(const torch::Tensor& pixels_in, const torch::Tensor& ring_in,
                                   const torch::Tensor& planes_in, bool fused) {
  using region_detail::kFeatures;
  const torch::Tensor pixels = pixels_in.to(torch::kCPU, torch::kFloat32).contiguous();
  const torch::Tensor ring = ring_in.to(torch::kCPU, torch::kFloat32);
  const torch::Tensor planes = planes_in.to(torch::kCPU, torch::kFloat32);
  if (pixels.dim() != 2 || pixels.size(1) != kFeatures || ring.dim() != 2 || ring.size(1) != kFeatures ||
      planes.dim() != 2 || planes.size(1) != 3 || planes.size(0) != ring.size(0) || ring.size(0) == 0)
    fail("region surface: the ring's weights need (n, {0}) pixels, (m, {0}) ring features and (m, 3) planes, m > 0",
         kFeatures);
  const int64_t n = pixels.size(0), m = ring.size(0);
  const torch::Tensor bias = ring.pow(2).sum(1);  // (m): |b|^2, the same for every pixel's logit
  torch::Tensor weighted = torch::empty({n, 3}, torch::kFloat32);
  if (fused && cpu_features().has(CpuIsa::Avx2)) {
    // Padded to whole vectors with ring pixels that weigh nothing.
    const int64_t padded = (m + 7) / 8 * 8;
    auto pad = [&](const torch::Tensor& rows, float value) {  // (C, m) -> (C, padded), contiguous
      return torch::constant_pad_nd(rows, {0, padded - m}, value).contiguous();
    };
    const torch::Tensor ring_rows = pad(ring.t(), 0), planes_rows = pad(planes.t(), 0);
    const torch::Tensor bias_row = pad(bias.view({1, m}), 1e30f);
    const region_detail::RingWeightsIo io{pixels.data_ptr<float>(), ring_rows.data_ptr<float>(),
                                          bias_row.data_ptr<float>(), planes_rows.data_ptr<float>(), padded,
                                          weighted.data_ptr<float>()};
    parallel_range(n, 64, at::get_num_threads(),
                   [&](int64_t begin, int64_t end) { region_detail::weighted_planes_avx2(io, begin, end); });
    return weighted;
  }
  for (int64_t start = 0; start < n; start += 4096) {
    const int64_t count = std::min<int64_t>(4096, n - start);
    const torch::Tensor weights =
        torch::softmax(2 * pixels.narrow(0, start, count).matmul(ring.t()) - bias.view({1, m}), 1);
    weighted.narrow(0, start, count).copy_(weights.matmul(planes));
  }
  return weighted;
}

bool region_surface_may_apply(const SceneInput& input, const MeasuredDepth& measured,
                              const RegionSurfaceOptions& options) {
  return options.opacity > 0 && !input.views.empty() && input.views.front().mask.has_value() &&
         !measured.depth.empty() && measured.depth.front().defined();
}

RegionSurface put_region_on_surface(GaussianMaps& maps, const SceneInput& input, const MeasuredDepth& measured,
                                    int mask_margin, const RegionSurfaceOptions& options) {
  check_region_surface_options(options);
  RegionSurface done;
  if (!region_surface_may_apply(input, measured, options)) return done;
  const PreparedView& reference = input.views.front();
  const torch::Tensor& depth = measured.depth.front();
  const int64_t H = maps.depth.size(3), W = maps.depth.size(4);
  if (depth.size(0) != H || depth.size(1) != W) return done;
  torch::InferenceMode inference;  // the maps are the network's inference tensors
  const torch::Tensor region = grown_mask(reference, mask_margin);
  const Image& rgb = reference.rgb;
  const torch::Tensor colour =
      torch::from_blob(const_cast<float*>(rgb.pixels.data()), {H, W, rgb.channels}, torch::kFloat32)
          .index({Slice(), Slice(), Slice(0, 3)})
          .permute({2, 0, 1});
  done.slopes = measured.from == MeasuredFrom::depth_maps;
  const torch::Tensor completed = depth_from_surroundings(depth, region, colour, done.slopes, options, &done.ring);
  // Pixels of the region without a depth keep the network's Gaussians.
  const torch::Tensor take = region.logical_and(completed.gt(0));
  if (!take.any().item<bool>()) return done;
  // Neighbours outside the region keep their own depth, so that the splats at its edge meet them.
  torch::Tensor surface = torch::where(take, completed, maps.depth[0][0][0].to(torch::kCPU, torch::kFloat32));
  if (options.far_side) {
    const FarSide far =
        flying_pixels_to_far_side(torch::where(take, completed, depth.to(torch::kCPU, torch::kFloat32)), {});
    const torch::Tensor moved = far.moved.logical_and(take);
    surface = torch::where(moved, far.depth, surface);
    done.far_side = moved.sum().item<int64_t>();
  }
  const GaussianSet splats = surface_gaussians(input.input.view_cameras.front(), surface, take, rgb,
                                               static_cast<float>(options.opacity), /*width=*/0.25);
  done.pixels = take.flatten().nonzero().squeeze(1);
  write_splats(maps, 0, done.pixels, splats, surface.index({take}), /*colours=*/true);
  done.gaussians = splats.size();
  return done;
}

void check_region_surface_options(const RegionSurfaceOptions& o) {
  if (!(o.opacity >= 0 && o.opacity <= 1))
    fail("region surface: the opacity must be between 0 and 1 (got {})", o.opacity);
  if (!(o.spatial > 0)) fail("region surface: the spatial width must be above 0 (got {})", o.spatial);
  if (!(o.colour > 0)) fail("region surface: the colour width must be above 0 (got {})", o.colour);
  if (o.gap < 0) fail("region surface: the ring's gap must be 0 or more pixels (got {})", o.gap);
  if (!(o.reach > 0)) fail("region surface: the ring's reach must be above 0 (got {})", o.reach);
  if (o.ring_samples < 1) fail("region surface: the ring needs at least one sample (got {})", o.ring_samples);
  if (!(o.slope_window > 0) || !(o.slope_fit > 0))
    fail("region surface: the slopes' window and fit must be above 0 (got {}, {})", o.slope_window, o.slope_fit);
}

nlohmann::json describe_region_surface(const RegionSurfaceOptions& options, const RegionSurface& done) {
  return {{"opacity", options.opacity},
          {"spatial", options.spatial},
          {"colour", options.colour},
          {"slopes", done.slopes},
          {"far_side", done.far_side},
          {"ring", done.ring},
          {"gaussians", done.gaussians}};
}

}  // namespace ii
