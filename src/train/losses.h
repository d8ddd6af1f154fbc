#pragma once
// The training loss per rendered target view (spec §6.4): 1.0 · MSE + 0.5 · perceptual, on
// images in [−1, 1]. The official perceptual term is LPIPS-VGG; its backbone weights are not
// redistributable, so without them a weight-free substitute is used: 1 − SSIM (11×11
// Gaussian window, on the images mapped to [0, 1]). SSIM compares local means, contrasts and
// structure like LPIPS's feature statistics do, needs no weights, and is differentiable.
// Loss values are therefore only comparable between runs with the same perceptual term.
// An optional depth term (depth_weight) supervises the inputs' own predicted depth.
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "common/torch.h"

namespace ii {

class Lpips;

struct LossOptions {
  double mse_weight = 1.0;
  double perceptual_weight = 0.5;
  // auto: LPIPS-VGG when its backbone is supplied (option or $INSTAINPAINT_LPIPS_VGG), else
  // 1 − SSIM.  lpips: LPIPS-VGG or an error.  ssim: 1 − SSIM.  none: MSE only.
  std::string perceptual = "auto";
  std::optional<std::filesystem::path> lpips_backbone, lpips_heads;
  // Weight of depth_loss on the inputs' predicted depth where samples carry depth maps
  // (synthetic scenes). Not in the official recipe, hence 0 by default; it teaches a small
  // model geometry far sooner than rendering losses alone.
  double depth_weight = 0.0;
  // Weight of the own-view term: each input's own Gaussians rendered at its camera against its
  // image outside its mask (MSE). A one-Gaussian-per-pixel model should give its inputs back; the
  // novel-view loss alone lets it blur them (wide, faint Gaussians hide misplaced depth).
  double own_view_weight = 0.0;
};

// Mean |log(predicted) − log(target)| over the pixels where target > 0 (0 when there are
// none): scale-free, so near and far surfaces count alike. Shapes must match.
torch::Tensor depth_loss(const torch::Tensor& predicted, const torch::Tensor& target);

struct LossTerms {
  torch::Tensor total;       // weighted sum (scalar)
  torch::Tensor mse;         // mean squared error (scalar, [−1, 1] range)
  torch::Tensor perceptual;  // LPIPS or 1 − SSIM (scalar; 0 when none)
};

class ImageLoss {
 public:
  explicit ImageLoss(const LossOptions& options = {});
  ~ImageLoss();
  ImageLoss(ImageLoss&&) noexcept;

  // prediction, target: (N, 3, H, W) in [−1, 1]; each term is the mean over the N images.
  // Differentiable with respect to the prediction.
  LossTerms operator()(const torch::Tensor& prediction, const torch::Tensor& target) const;

  // "lpips-vgg", "1-ssim" or "none".
  const std::string& perceptual_name() const { return perceptual_name_; }
  const LossOptions& options() const { return options_; }
  void to(const torch::Device& device);

 private:
  LossOptions options_;
  std::string perceptual_name_;
  std::unique_ptr<Lpips> lpips_;
};

}  // namespace ii
