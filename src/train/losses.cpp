#include "train/losses.h"

#include <spdlog/spdlog.h>

#include <fmt/ranges.h>

#include "common/error.h"
#include "eval/lpips.h"
#include "eval/metrics.h"

namespace ii {

ImageLoss::ImageLoss(const LossOptions& options) : options_(options) {
  const std::string& kind = options.perceptual;
  if (kind != "auto" && kind != "lpips" && kind != "ssim" && kind != "none")
    fail("--perceptual must be auto, lpips, ssim or none, got '{}'", kind);
  if (kind == "none" || options.perceptual_weight == 0) {
    perceptual_name_ = "none";
    return;
  }
  const bool have_backbone = lpips_backbone_path(LpipsNet::vgg, options.lpips_backbone).has_value();
  if (kind == "lpips" || (kind == "auto" && have_backbone)) {
    lpips_ = std::make_unique<Lpips>(Lpips::load(LpipsNet::vgg, options.lpips_backbone, options.lpips_heads));
    perceptual_name_ = "lpips-vgg";
    return;
  }
  if (kind == "auto")
    spdlog::info("perceptual loss: 1 - SSIM (LPIPS-VGG needs the VGG16 backbone: --lpips-vgg or ${})",
                 lpips_backbone_env_var(LpipsNet::vgg));
  perceptual_name_ = "1-ssim";
}

ImageLoss::~ImageLoss() = default;
ImageLoss::ImageLoss(ImageLoss&&) noexcept = default;

LossTerms ImageLoss::operator()(const torch::Tensor& prediction, const torch::Tensor& target) const {
  if (prediction.dim() != 4 || prediction.size(1) != 3 || prediction.sizes() != target.sizes())
    fail("loss: prediction [{}] and target [{}] must both be (N, 3, H, W)", fmt::join(prediction.sizes(), ", "),
         fmt::join(target.sizes(), ", "));
  LossTerms t;
  t.mse = torch::mse_loss(prediction, target);
  if (lpips_) {
    t.perceptual = lpips_->forward(prediction, target).mean();
  } else if (perceptual_name_ == "1-ssim") {
    t.perceptual = 1.0 - ssim((prediction + 1) * 0.5, (target + 1) * 0.5).mean();
  } else {
    t.perceptual = torch::zeros({}, prediction.options());
  }
  t.total = options_.mse_weight * t.mse + options_.perceptual_weight * t.perceptual;
  return t;
}

torch::Tensor depth_loss(const torch::Tensor& predicted, const torch::Tensor& target) {
  if (predicted.sizes() != target.sizes())
    fail("depth loss: prediction [{}] and target [{}] differ in shape", fmt::join(predicted.sizes(), ", "),
         fmt::join(target.sizes(), ", "));
  const torch::Tensor known = target > 0;
  const torch::Tensor count = known.sum();
  // The clamp keeps log finite where the prediction underflows; masked pixels get no gradient.
  const torch::Tensor error = (predicted.clamp_min(1e-6).log() - target.clamp_min(1e-6).log()).abs();
  return torch::where(known, error, torch::zeros_like(error)).sum() / count.clamp_min(1);
}

void ImageLoss::to(const torch::Device& device) {
  if (lpips_) lpips_->to(device);
}

}  // namespace ii
