#include "eval/metrics.h"

#include <torch/nn/functional.h>
#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/ranges.h>

#include "common/error.h"

namespace ii {

namespace {

constexpr int kSsimWindow = 11;
constexpr double kSsimSigma = 1.5;
constexpr double kSsimC1 = 0.01 * 0.01;
constexpr double kSsimC2 = 0.03 * 0.03;

std::string shape_text(const torch::Tensor& t) { return fmt::format("[{}]", fmt::join(t.sizes(), ", ")); }

// (C, H, W) -> (1, C, H, W); (N, C, H, W) as is.
torch::Tensor as_batch(const torch::Tensor& t, const char* what, const char* name) {
  if (!t.defined()) fail("{}: {} is undefined", what, name);
  if (t.dim() == 3) return t.unsqueeze(0);
  if (t.dim() == 4) return t;
  fail("{}: {} must be (N, C, H, W) or (C, H, W), got shape {}", what, name, shape_text(t));
}

std::pair<torch::Tensor, torch::Tensor> image_pair(const torch::Tensor& a, const torch::Tensor& b, const char* what) {
  torch::Tensor x = as_batch(a, what, "first image"), y = as_batch(b, what, "second image");
  if (x.sizes() != y.sizes()) fail("{}: the images differ in shape: {} vs {}", what, shape_text(x), shape_text(y));
  if (!x.is_floating_point() || !y.is_floating_point()) fail("{}: images must be floating point", what);
  if (y.scalar_type() != x.scalar_type()) y = y.to(x.scalar_type());
  return {x, y};
}

// Mask as (N, 1, H, W) float weights in {0, 1} (> 0.5), matching `like` (N, C, H, W).
// The mask as {0, 1} of (n, 1, h, w) in `dtype`; `images` is the images' shape for the error.
torch::Tensor as_mask(const torch::Tensor& mask, int64_t n, int64_t h, int64_t w, torch::ScalarType dtype,
                      const std::string& images, const char* what) {
  if (!mask.defined()) fail("{}: the mask is undefined", what);
  torch::Tensor m = mask;
  if (m.dim() == 2)
    m = m.unsqueeze(0).unsqueeze(0);
  else if (m.dim() == 3)
    m = m.unsqueeze(0);
  if (m.dim() != 4 || m.size(1) != 1 || m.size(2) != h || m.size(3) != w || (m.size(0) != n && m.size(0) != 1))
    fail("{}: mask of shape {} does not fit images of shape {} (expected (N or 1, 1, H, W))", what, shape_text(mask),
         images);
  return (m > 0.5).to(dtype).expand({n, 1, h, w});
}

torch::Tensor as_mask(const torch::Tensor& mask, const torch::Tensor& like, const char* what) {
  return as_mask(mask, like.size(0), like.size(2), like.size(3), like.scalar_type(), shape_text(like), what);
}

torch::Tensor gaussian_window(const torch::TensorOptions& options) {
  const torch::Tensor x =
      torch::arange(kSsimWindow, torch::TensorOptions().dtype(torch::kFloat64)) - (kSsimWindow - 1) / 2;
  const torch::Tensor g = torch::exp(-(x * x) / (2 * kSsimSigma * kSsimSigma));
  return (g / g.sum()).to(options);
}

// Separable "valid" Gaussian filtering of every channel: (N, C, H, W) -> (N, C, H-10, W-10).
torch::Tensor gaussian_filter_valid(const torch::Tensor& x) {
  const int64_t channels = x.size(1);
  const torch::Tensor g = gaussian_window(x.options());
  const torch::Tensor row = g.view({1, 1, 1, kSsimWindow}).expand({channels, 1, 1, kSsimWindow});
  const torch::Tensor col = g.view({1, 1, kSsimWindow, 1}).expand({channels, 1, kSsimWindow, 1});
  namespace F = torch::nn::functional;
  const torch::Tensor h = F::conv2d(x, row, F::Conv2dFuncOptions().groups(channels));
  return F::conv2d(h, col, F::Conv2dFuncOptions().groups(channels));
}

// Per-channel SSIM map, (N, C, H-10, W-10).
torch::Tensor ssim_channel_map(const torch::Tensor& x, const torch::Tensor& y, const char* what) {
  if (x.size(2) < kSsimWindow || x.size(3) < kSsimWindow)
    fail("{}: images of {}x{} pixels are smaller than the {}x{} SSIM window", what, x.size(3), x.size(2), kSsimWindow,
         kSsimWindow);
  // One filtering pass over the five statistics at once.
  const int64_t c = x.size(1);
  const torch::Tensor stats = gaussian_filter_valid(torch::cat({x, y, x * x, y * y, x * y}, 1));
  const torch::Tensor mu_x = stats.narrow(1, 0, c), mu_y = stats.narrow(1, c, c);
  const torch::Tensor var_x = stats.narrow(1, 2 * c, c) - mu_x * mu_x;
  const torch::Tensor var_y = stats.narrow(1, 3 * c, c) - mu_y * mu_y;
  const torch::Tensor cov = stats.narrow(1, 4 * c, c) - mu_x * mu_y;
  return ((2 * mu_x * mu_y + kSsimC1) * (2 * cov + kSsimC2)) /
         ((mu_x * mu_x + mu_y * mu_y + kSsimC1) * (var_x + var_y + kSsimC2));
}

torch::Tensor psnr_from_mse(const torch::Tensor& m) { return -10.0 * torch::log10(m); }

}  // namespace

torch::Tensor mse(const torch::Tensor& a, const torch::Tensor& b) {
  const auto [x, y] = image_pair(a, b, "mse");
  return (x - y).pow(2).flatten(1).mean(1);
}

torch::Tensor masked_mse(const torch::Tensor& a, const torch::Tensor& b, const torch::Tensor& mask) {
  const auto [x, y] = image_pair(a, b, "masked mse");
  const torch::Tensor m = as_mask(mask, x, "masked mse");
  const torch::Tensor squared = ((x - y).pow(2) * m).flatten(1).sum(1);
  return squared / (m.flatten(1).sum(1) * x.size(1));  // 0/0 = NaN for an empty mask
}

torch::Tensor psnr(const torch::Tensor& a, const torch::Tensor& b) {
  const auto [x, y] = image_pair(a, b, "psnr");
  return psnr_from_mse(mse(x.clamp(0, 1), y.clamp(0, 1)));
}

torch::Tensor masked_psnr(const torch::Tensor& a, const torch::Tensor& b, const torch::Tensor& mask) {
  const auto [x, y] = image_pair(a, b, "masked psnr");
  return psnr_from_mse(masked_mse(x.clamp(0, 1), y.clamp(0, 1), as_mask(mask, x, "masked psnr")));
}

torch::Tensor ssim_map(const torch::Tensor& a, const torch::Tensor& b) {
  const auto [x, y] = image_pair(a, b, "ssim");
  return ssim_channel_map(x, y, "ssim").mean(1, /*keepdim=*/true);
}

torch::Tensor ssim(const torch::Tensor& a, const torch::Tensor& b) { return ssim_map(a, b).flatten(1).mean(1); }

torch::Tensor masked_ssim(const torch::Tensor& a, const torch::Tensor& b, const torch::Tensor& mask) {
  const auto [x, y] = image_pair(a, b, "masked ssim");
  return masked_ssim_of_map(ssim_channel_map(x, y, "masked ssim").mean(1, true), as_mask(mask, x, "masked ssim"));
}

torch::Tensor masked_ssim_of_map(const torch::Tensor& map, const torch::Tensor& mask) {
  const int64_t r = kSsimWindow / 2;
  const torch::Tensor m =
      as_mask(mask, map.size(0), map.size(2) + 2 * r, map.size(3) + 2 * r, map.scalar_type(),
              fmt::format("[{}, C, {}, {}]", map.size(0), map.size(2) + 2 * r, map.size(3) + 2 * r), "masked ssim");
  const torch::Tensor inner = m.narrow(2, r, map.size(2)).narrow(3, r, map.size(3));
  return (map * inner).flatten(1).sum(1) / inner.flatten(1).sum(1);
}

std::optional<PixelBox> mask_bounding_box(const torch::Tensor& mask) {
  torch::Tensor m = mask;
  while (m.dim() > 2 && m.size(0) == 1) m = m.squeeze(0);
  if (m.dim() != 2) fail("mask bounding box: expected one (H, W) mask, got shape {}", shape_text(mask));
  const torch::Tensor inside = (m > 0.5).cpu();
  const torch::Tensor rows = inside.any(1), cols = inside.any(0);
  if (!rows.any().item<bool>()) return std::nullopt;
  const torch::Tensor r = rows.nonzero(), c = cols.nonzero();
  PixelBox box;
  box.y0 = static_cast<int>(r.min().item<int64_t>());
  box.y1 = static_cast<int>(r.max().item<int64_t>()) + 1;
  box.x0 = static_cast<int>(c.min().item<int64_t>());
  box.x1 = static_cast<int>(c.max().item<int64_t>()) + 1;
  return box;
}

std::optional<PixelBox> mask_bounding_box(const Image& mask) {
  if (mask.channels != 1) fail("mask bounding box: expected a 1-channel mask, got {} channels", mask.channels);
  PixelBox box{mask.width, mask.height, 0, 0};
  for (int y = 0; y < mask.height; ++y)
    for (int x = 0; x < mask.width; ++x)
      if (mask.at(y, x) > 0.5f) {
        box.x0 = std::min(box.x0, x);
        box.y0 = std::min(box.y0, y);
        box.x1 = std::max(box.x1, x + 1);
        box.y1 = std::max(box.y1, y + 1);
      }
  if (box.empty()) return std::nullopt;
  return box;
}

PixelBox grow_box(const PixelBox& box, int min_width, int min_height, int image_width, int image_height) {
  auto grow = [](int lo, int hi, int min_size, int limit) {
    const int size = std::min(std::max(hi - lo, min_size), limit);
    int start = lo - (size - (hi - lo)) / 2;
    start = std::clamp(start, 0, limit - size);
    return std::pair<int, int>{start, start + size};
  };
  const auto [x0, x1] = grow(box.x0, box.x1, min_width, image_width);
  const auto [y0, y1] = grow(box.y0, box.y1, min_height, image_height);
  return {x0, y0, x1, y1};
}

torch::Tensor crop_to_box(const torch::Tensor& t, const PixelBox& box) {
  const int64_t h = t.size(-2), w = t.size(-1);
  if (box.empty() || box.x0 < 0 || box.y0 < 0 || box.x1 > w || box.y1 > h)
    fail("crop: box [{}, {}) x [{}, {}) is empty or outside the {}x{} image", box.x0, box.x1, box.y0, box.y1, w, h);
  return t.narrow(-2, box.y0, box.height()).narrow(-1, box.x0, box.width());
}

double box_psnr(const torch::Tensor& a, const torch::Tensor& b, const torch::Tensor& mask) {
  const auto box = mask_bounding_box(mask);
  if (!box) return std::numeric_limits<double>::quiet_NaN();
  return box_psnr_ssim(a, b, *box)[0].item<double>();
}

double box_ssim(const torch::Tensor& a, const torch::Tensor& b, const torch::Tensor& mask) {
  const auto box = mask_bounding_box(mask);
  if (!box) return std::numeric_limits<double>::quiet_NaN();
  return box_psnr_ssim(a, b, *box)[1].item<double>();
}

torch::Tensor box_psnr_ssim(const torch::Tensor& a, const torch::Tensor& b, const PixelBox& box,
                            const torch::Tensor& map) {
  const PixelBox grown =
      grow_box(box, kSsimWindow, kSsimWindow, static_cast<int>(a.size(-1)), static_cast<int>(a.size(-2)));
  // The grown box's SSIM: its valid positions are the whole image's map positions whose
  // windows lie inside the box (the same pixels and weights), when that map is at hand.
  const torch::Tensor box_ssim =
      map.defined() ? map.narrow(2, grown.y0, grown.height() - kSsimWindow + 1)
                          .narrow(3, grown.x0, grown.width() - kSsimWindow + 1)
                          .flatten(1)
                          .mean(1)[0]
                    : ssim(crop_to_box(a, grown), crop_to_box(b, grown))[0];
  return torch::stack({psnr(crop_to_box(a, box), crop_to_box(b, box))[0].to(torch::kFloat), box_ssim.to(torch::kFloat)});
}

}  // namespace ii
