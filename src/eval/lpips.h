#pragma once
// LPIPS v0.1 (Zhang et al. 2018): a fixed ImageNet backbone (VGG16 or AlexNet features) and
// the published non-negative 1×1 "linear" heads. Per backbone stage: features unit-normalised
// along channels (eps 1e-10), squared difference, head, spatial mean; summed over stages.
//
// The heads are read from the converted safetensors files (shared/data/lpips/{vgg,alex}.
// safetensors). The backbone weights are not redistributable with this project: the user
// supplies torchvision's ImageNet state dict (vgg16-397923af.pth / alexnet-owt-7be5be79.pth,
// read with the restricted .pth reader; or the same keys as safetensors), named by an option
// or by the environment variable INSTAINPAINT_LPIPS_VGG / INSTAINPAINT_LPIPS_ALEX.
//
// Lpips::forward is differentiable with respect to its inputs (all weights are frozen), so it
// can serve as a training loss.
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "common/torch.h"

#include "eval/weights.h"

namespace ii {

enum class LpipsNet { vgg, alex };

const char* lpips_net_name(LpipsNet net);            // "vgg" / "alex"
LpipsNet parse_lpips_net(const std::string& name);   // throws on anything else
const char* lpips_backbone_env_var(LpipsNet net);    // INSTAINPAINT_LPIPS_VGG / _ALEX
const char* lpips_backbone_file_name(LpipsNet net);  // torchvision's file name
// Head channel counts per stage: vgg 64,128,256,512,512; alex 64,192,384,256,256.
std::vector<int64_t> lpips_stage_channels(LpipsNet net);

// The backbone weight file to use: `explicit_path` if given, else the environment variable,
// else nullopt. An explicit or environment path that does not exist is an error.
std::optional<std::filesystem::path> lpips_backbone_path(LpipsNet net,
                                                         const std::optional<std::filesystem::path>& explicit_path);
// The message given when no backbone file is available: which file, where to get it, how to
// name it.
std::string lpips_missing_backbone_message(LpipsNet net);

// Default location of the heads: $INSTAINPAINT_LPIPS_HEADS/<net>.safetensors if set, else
// ../shared/data/lpips/<net>.safetensors relative to the current directory and to the
// executable's folder's parent.
std::optional<std::filesystem::path> default_lpips_heads_path(LpipsNet net);

// The five head weights, each (1, C, 1, 1), keys linK.model.1.weight (K = 0..4). Checked.
std::vector<torch::Tensor> read_lpips_heads(const std::filesystem::path& path, LpipsNet net);

class Lpips {
 public:
  // Loads the heads and the backbone (torchvision keys `features.<i>.weight/bias`; other keys
  // such as the classifier are ignored). Errors name the file and the missing/mis-shaped key.
  Lpips(LpipsNet net, const std::filesystem::path& backbone_file, const std::filesystem::path& heads_file);
  // From tensors in memory (`source` names them in errors); heads as read_lpips_heads gives.
  Lpips(LpipsNet net, const WeightMap& backbone, std::vector<torch::Tensor> heads, const std::string& source);
  // The backbone from `backbone_file` if given, else from the environment variable; heads
  // from `heads_file` if given, else default_lpips_heads_path(). Throws
  // lpips_missing_backbone_message() when no backbone file is available.
  static Lpips load(LpipsNet net, const std::optional<std::filesystem::path>& backbone_file = std::nullopt,
                    const std::optional<std::filesystem::path>& heads_file = std::nullopt);

  // Per-image distance (N) for (N, 3, H, W) (or (3, H, W)) inputs in [−1, 1] (the upstream
  // convention; `lpips.LPIPS()(a, b)`). Differentiable with respect to a and b.
  torch::Tensor forward(const torch::Tensor& a, const torch::Tensor& b) const;
  torch::Tensor operator()(const torch::Tensor& a, const torch::Tensor& b) const { return forward(a, b); }

  // Spatial map (N, 1, H, W): each stage's head output upsampled bilinearly to the input
  // size, summed over stages (upstream `spatial=True`).
  torch::Tensor spatial_map(const torch::Tensor& a, const torch::Tensor& b) const;

  // Masked LPIPS as the official helper defines it (spec §7): both images multiplied by the
  // mask in [0, 1] space, then the spatial map averaged over pixels with mask > 0.5.
  // Inputs in [−1, 1], mask (N, 1, H, W) or (1, H, W); (N), NaN for an empty mask.
  torch::Tensor masked(const torch::Tensor& a, const torch::Tensor& b, const torch::Tensor& mask) const;

  // Per-stage normalised features (for tests and analysis), input (N, 3, H, W) in [−1, 1].
  std::vector<torch::Tensor> features(const torch::Tensor& x) const;

  LpipsNet net() const { return net_; }
  const std::vector<torch::Tensor>& heads() const { return heads_; }
  // Moves every weight to `device` (inputs must then be there too).
  void to(const torch::Device& device);

 private:
  struct Conv {
    torch::Tensor weight, bias;
    int64_t stride = 1, padding = 0;
  };
  // A max pool (kernel 0 = none) then convolutions, each followed by ReLU; the stage's
  // output is the last ReLU's.
  struct Stage {
    int64_t pool_kernel = 0, pool_stride = 0;
    std::vector<Conv> convs;
  };
  // Per stage: the head applied to the squared difference of normalised features, (N, 1, h, w).
  std::vector<torch::Tensor> stage_distances(const torch::Tensor& a, const torch::Tensor& b) const;

  LpipsNet net_;
  std::vector<Stage> stages_;
  std::vector<torch::Tensor> heads_;
};

}  // namespace ii
