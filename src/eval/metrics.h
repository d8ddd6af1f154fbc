#pragma once
// Full-reference image metrics over torch tensors, differentiable so that training can use
// them as losses. Images are (N, 3, H, W) (or (3, H, W), treated as N = 1) with values in
// [0, 1]; masks are (N, 1, H, W) (or (1, H, W) / (H, W)) with 1 = inside the region.
// Every function returns one value per image, shape (N); take .mean() for a loss.
//
// Definitions (what is standard, and what the official helper of spec §7 does):
//  * PSNR = −10 log10(MSE), MSE over all pixels and channels (masked: over pixels with
//    mask > 0.5, all channels). Identical images give +inf.
//  * SSIM (Wang et al. 2004): 11×11 Gaussian window with σ = 1.5, C1 = 0.01², C2 = 0.03²
//    (data range 1), population statistics, computed per channel on the "valid" positions
//    (windows entirely inside the image: the map is (H−10)×(W−10)), averaged over channels
//    and positions. Equal to scikit-image's structural_similarity with gaussian_weights,
//    sigma 1.5, use_sample_covariance False, data_range 1. Images need H, W >= 11.
//  * Masked SSIM: the SSIM map averaged over the valid positions whose centre pixel is in
//    the mask (so an all-ones mask gives exactly ssim()). NaN when no such position exists.
//  * Bounding-box variants: the metric on the crop of the mask's bounding box (see
//    mask_bounding_box); for SSIM the box is grown to at least 11×11 inside the image.
#include <optional>

#include "common/torch.h"

#include "io/image.h"

namespace ii {

// Per-image mean squared error, (N).
torch::Tensor mse(const torch::Tensor& a, const torch::Tensor& b);
torch::Tensor masked_mse(const torch::Tensor& a, const torch::Tensor& b, const torch::Tensor& mask);

// Per-image PSNR in dB for data range 1, (N). Inputs are clamped to [0, 1] first (as the
// official helper does); +inf for identical images.
torch::Tensor psnr(const torch::Tensor& a, const torch::Tensor& b);
torch::Tensor masked_psnr(const torch::Tensor& a, const torch::Tensor& b, const torch::Tensor& mask);

// SSIM map, (N, 1, H−10, W−10): the per-position SSIM averaged over the channels.
torch::Tensor ssim_map(const torch::Tensor& a, const torch::Tensor& b);
// Per-image SSIM, (N). Differentiable with respect to both inputs.
torch::Tensor ssim(const torch::Tensor& a, const torch::Tensor& b);
torch::Tensor masked_ssim(const torch::Tensor& a, const torch::Tensor& b, const torch::Tensor& mask);
// masked_ssim of an ssim_map computed once (one map, several masks).
torch::Tensor masked_ssim_of_map(const torch::Tensor& map, const torch::Tensor& mask);

// Half-open pixel box [x0, x1) × [y0, y1).
struct PixelBox {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  int width() const { return x1 - x0; }
  int height() const { return y1 - y0; }
  bool empty() const { return x1 <= x0 || y1 <= y0; }
};

// Tight bounding box of the pixels with mask > 0.5 (a (H, W), (1, H, W) or (1, 1, H, W)
// tensor, or a 1-channel Image); nullopt when the mask is empty.
std::optional<PixelBox> mask_bounding_box(const torch::Tensor& mask);
std::optional<PixelBox> mask_bounding_box(const Image& mask);

// `box` grown symmetrically (as far as the image allows, then shifted to stay inside) to at
// least min_width × min_height; clamped to the image when the image itself is smaller.
PixelBox grow_box(const PixelBox& box, int min_width, int min_height, int image_width, int image_height);

// Crop of (..., H, W) tensors to a box (a view, differentiable).
torch::Tensor crop_to_box(const torch::Tensor& t, const PixelBox& box);

// PSNR and SSIM of the crops of a single image pair (3, H, W) / (1, 3, H, W) to the mask's
// bounding box. NaN when the mask is empty.
double box_psnr(const torch::Tensor& a, const torch::Tensor& b, const torch::Tensor& mask);
double box_ssim(const torch::Tensor& a, const torch::Tensor& b, const torch::Tensor& mask);
// Both for a box known on the host, as a (2) float tensor on the inputs' device: nothing waits
// for a GPU (box_psnr and box_ssim find the box on the host and read each value back). With
// the images' ssim_map the box's SSIM is read from it (the same values, no second filtering).
torch::Tensor box_psnr_ssim(const torch::Tensor& a, const torch::Tensor& b, const PixelBox& box,
                            const torch::Tensor& map = {});

}  // namespace ii
