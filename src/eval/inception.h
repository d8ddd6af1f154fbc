#pragma once
// Inception-v3 as used for FID (pytorch-fid's port of the 2015-12-05 TensorFlow graph): the
// network up to the final average pool, giving 2048 features per image. Built from plain
// torch ops with batch norm folded into the convolutions.
//
// Weights: the pytorch-fid state dict `pt_inception-2015-12-05-6726825d.pth` (the standard
// for comparable FID numbers), read with the restricted .pth reader, or the same keys as
// safetensors; named by --inception or $INSTAINPAINT_FID_INCEPTION. The structure follows
// that port exactly: inputs resized bilinearly to 299×299 and mapped to [−1, 1]; average
// pools inside the mixed blocks exclude padding; the last block's pool branch is a max pool.
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "common/torch.h"

#include "eval/weights.h"

namespace ii {

const char* inception_env_var();  // INSTAINPAINT_FID_INCEPTION
// The explicit file if given (must exist), else $INSTAINPAINT_FID_INCEPTION, else nullopt.
std::optional<std::filesystem::path> inception_weights_path(const std::optional<std::filesystem::path>& explicit_path);
std::string inception_missing_message();

// Every convolution of the network: key prefix (e.g. "Mixed_5b.branch5x5_2"), in/out channels,
// kernel (h, w), stride, padding (h, w). Weights live under PREFIX.conv.weight and
// PREFIX.bn.{weight,bias,running_mean,running_var}.
struct InceptionConvSpec {
  std::string name;
  int64_t in, out, kh, kw, stride, ph, pw;
};
const std::vector<InceptionConvSpec>& inception_conv_specs();

class InceptionFeatures {
 public:
  // From weights in memory (checked: every key present with its shape; "fc" must have 1008
  // outputs, the FID network's, not torchvision's 1000). `source` names them in errors.
  InceptionFeatures(const WeightMap& weights, const std::string& source);
  static InceptionFeatures load(const std::filesystem::path& file);

  // (N, 3, H, W) in [0, 1] -> (N, 2048). Images are processed `batch` at a time.
  torch::Tensor forward(const torch::Tensor& images, int64_t batch = 16) const;

  void to(const torch::Device& device);
  // The input size (299 for FID); smaller sizes (at least 75) only for quick tests.
  int64_t input_size = 299;

 private:
  struct Conv {
    torch::Tensor weight, bias;  // batch norm folded in
    int64_t stride = 1, ph = 0, pw = 0;
  };
  torch::Tensor conv(const std::string& name, const torch::Tensor& x) const;
  torch::Tensor block_a(const std::string& name, const torch::Tensor& x) const;
  torch::Tensor block_b(const std::string& name, const torch::Tensor& x) const;
  torch::Tensor block_c(const std::string& name, const torch::Tensor& x) const;
  torch::Tensor block_d(const std::string& name, const torch::Tensor& x) const;
  torch::Tensor block_e(const std::string& name, const torch::Tensor& x, bool max_pool_branch) const;
  torch::Tensor features_batch(const torch::Tensor& x) const;

  std::map<std::string, Conv> convs_;
};

}  // namespace ii
