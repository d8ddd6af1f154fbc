#pragma once
// The InstaInpaint network (spec §1-3): patch embedding of RGB+mask and Plücker rays, a
// transformer over all views' tokens jointly, five per-token Gaussian heads, unpatchify,
// activations, and positions from z-depth.
//
// Parameters are plain tensors under the official key names with weight norm folded
// (`...weight` instead of `weight_g`/`weight_v`); see model/checkpoint.h for loading.
#include <map>
#include <string>
#include <vector>

#include "common/torch.h"

#include "gaussians/gaussians.h"
#include "model/attention.h"
#include "model/config.h"

namespace ii {

struct NetworkOutput {
  torch::Tensor encoder_tokens;      // (B*V, h*w, D) after the encoder norm (cls dropped)
  torch::Tensor transformer_tokens;  // (B, V*h*w, D)
  GaussianMaps gaussians;
};

enum class Precision { Float32, BFloat16 };
const char* precision_name(Precision p);
// bf16 when the CPU has native bf16 dot products (AVX512-BF16 or AMX), else float32.
Precision default_cpu_precision();

// How forward() computes; every choice gives the same values up to rounding. The defaults are
// the fast path; the others reproduce slower implementations for benchmarks.
struct ExecutionOptions {
  AttentionForm attention = AttentionForm::Fastest;
  bool fused_heads = true;       // the five heads' first Linears as one matrix product
  bool cached_weights = true;    // bf16 weights converted once, not on every call as autocast does
  bool fused_norms = true;       // residual add + layer norm in one pass (CPU, model/layer_norm.h)
};

// Wall time of forward()'s stages, each summed over the blocks, in first-seen order. Measured
// on the CPU, where every operation has finished when it returns.
struct StageProfile {
  std::vector<std::pair<std::string, double>> ms;
  void add(const std::string& stage, double milliseconds);
  double total() const;
};

class Network {
 public:
  // Randomly initialised, or with uninitialised memory when `initialise` is false (for
  // weights that are loaded right after).
  explicit Network(const ModelConfig& config, bool initialise = true);

  const ModelConfig& config() const { return config_; }

  // Official key names (weight norm folded), in a fixed order.
  const std::vector<std::pair<std::string, torch::Tensor>>& named_parameters() const { return params_; }
  std::vector<torch::Tensor> parameters() const;

  // Copies values in by name. Strict: every parameter must be present with its exact shape
  // and no unknown key may remain; errors list what is missing or unexpected.
  void load(const std::map<std::string, torch::Tensor>& state, const std::string& source);
  // The same, taking the tensors over instead of copying them (a large checkpoint's weights
  // are not copied once more).
  void load(std::map<std::string, torch::Tensor>&& state, const std::string& source);

  // images: (B, V, C, H, W) with C = image_channels, RGB in [-1,1] then mask;
  // plucker: (B, V, 6, H, W); rays_o, rays_d_un: (B, V, H, W, 3).
  NetworkOutput forward(const torch::Tensor& images, const torch::Tensor& plucker,
                        const torch::Tensor& rays_o, const torch::Tensor& rays_d_un,
                        Precision precision = Precision::Float32) const;

  // Moves parameters (e.g. to CUDA); the bf16 weight cache is rebuilt lazily.
  void to(const torch::Device& device);
  // Replaces the parameter tensors (order and shapes of named_parameters()), e.g. with
  // weights computed from a training parametrisation, so gradients flow back into it.
  void set_parameters(const std::vector<torch::Tensor>& values);
  // Training memory: keep only each transformer block's input and recompute the block in
  // the backward pass (the official `use_checkpoint`). Same values and gradients.
  void set_activation_checkpointing(bool on) { checkpoint_blocks_ = on; }
  void set_requires_grad(bool requires_grad);
  void set_execution(const ExecutionOptions& options) { execution_ = options; }
  // forward() adds its stages' times to `profile` (none: nullptr); it must outlive the calls.
  void set_profile(StageProfile* profile) { profile_ = profile; }

 private:
  struct Block {
    torch::Tensor qkv, proj, fc1, fc2;  // Linear weights (out, in), no bias
  };
  struct Head {
    std::vector<torch::Tensor> layers;  // Linear weights; GELU between them
  };

  torch::Tensor& add(const std::string& name, torch::Tensor value);
  torch::Tensor linear(const torch::Tensor& x, const torch::Tensor& weight, Precision precision) const;
  torch::Tensor weight_for(const torch::Tensor& weight, Precision precision) const;
  // The heads' first Linear weights stacked along the output dimension.
  torch::Tensor fused_head_input_weight() const;
  void clear_weight_caches();
  // Throws the load error (missing, unexpected or misshapen tensors) when `state` does not fit.
  void check_fits(const std::map<std::string, torch::Tensor>& state, const std::string& source) const;

  ModelConfig config_;
  std::vector<std::pair<std::string, torch::Tensor>> params_;
  torch::Tensor proj_, proj_plucker_, cls_token_;
  std::vector<Block> blocks_;
  std::vector<Head> heads_;  // depth, rgb, opacity, scale, rotation
  ExecutionOptions execution_;
  bool checkpoint_blocks_ = false;
  StageProfile* profile_ = nullptr;
  mutable std::map<const void*, torch::Tensor> bf16_cache_;  // keyed by the fp32 storage
  mutable torch::Tensor fused_head_input_;                     // inference only; undefined = not built
};

// Unpatchify (spec §3.2): (B, V*h*w, p*p*C) head output -> (B, V, C, h*p, w*p).
torch::Tensor unpatchify(const torch::Tensor& x, int views, int h, int w, int patch, int channels);

}  // namespace ii
