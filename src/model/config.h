#pragma once
// Architecture of the InstaInpaint network (spec §1). Presets: `release` is the published
// 309M-parameter model; `tiny` is the official-layout parity fixture; `small` and `base`
// are the sizes we train ourselves; `mini` is the embedded default model's, `medium` one
// trained on a GPU.
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

namespace ii {

struct ModelConfig {
  std::string preset = "custom";
  int embed_dim = 1024;       // token width D
  int blocks = 24;            // transformer blocks
  int heads = 16;             // attention heads (head dim = D / heads)
  int patch = 8;              // patch size p
  int image_channels = 4;     // RGB + mask (3 for the stage-1 RGB-only model)
  int upsampler_dim = 1024;   // hidden width of each Gaussian head
  int upsampler_depth = 1;    // hidden layers per head
  int mlp_ratio = 4;          // transformer MLP hidden = mlp_ratio * D
  double depth_near = 0.0, depth_far = 500.0, depth_bias = -4.0;
  double scale_bias = -2.3, scale_min = 1e-4, scale_max = 0.3;
  double opacity_bias = -2.0;
  // Ours, not official: 0 = the scale head gives sizes in scene units at any working height (the
  // official model's, trained at 512 rows). N = its sizes are those of N-row pictures: at a
  // working height H above N they shrink by N / H, so that each Gaussian keeps its width in
  // pixels (a model trained at 128 rows and run at 512 otherwise draws every Gaussian four pixels
  // wide); below N they stay (the default model was trained at 64 rows too: twice as wide at 64
  // rows blurred the page's edit, web.browser.edit).
  int scale_reference_height = 0;
  // Ours, not official: the colour head predicts a correction to the input pixel's colour
  // instead of the colour itself. A small model trained briefly otherwise spends its steps
  // learning to copy colours through the transformer (and renders blurry averages).
  bool rgb_from_input = false;
  double encoder_ln_eps = 1e-6, ln_eps = 1e-5;

  static ModelConfig from_preset(const std::string& name);  // throws Error on unknown names
  static const char* preset_names();                        // "release, base, small, medium, mini, tiny"

  int head_dim() const { return embed_dim / heads; }
  int64_t parameter_count() const;  // including the inert cls token
  void validate() const;            // throws Error on inconsistent sizes

  // Multiply-adds x 2 of one forward pass over `views` images of height x width.
  double forward_flops(int views, int height, int width) const;

  nlohmann::json to_json() const;
  static ModelConfig from_json(const nlohmann::json& j);  // missing keys keep defaults
};

// Per-pixel channel counts of the five Gaussian heads, in official order.
struct GaussianHeads {
  static constexpr int count = 5;
  static constexpr const char* names[count] = {"depth", "rgb", "opacity", "scale", "rotation"};
  static constexpr int channels[count] = {1, 3, 1, 3, 4};
};

}  // namespace ii
