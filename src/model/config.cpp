#include "model/config.h"

#include "common/error.h"

namespace ii {

ModelConfig ModelConfig::from_preset(const std::string& name) {
  ModelConfig c;
  c.preset = name;
  if (name == "release") return c;
  if (name == "base") {
    c.embed_dim = 512;
    c.blocks = 12;
    c.heads = 8;
    c.upsampler_dim = 512;
    return c;
  }
  if (name == "small") {
    c.embed_dim = 256;
    c.blocks = 6;
    c.heads = 4;
    c.upsampler_dim = 256;
    return c;
  }
  if (name == "mini") {  // the embedded default model: trains in an hour on 2 CPU cores
    c.embed_dim = 192;
    c.blocks = 4;
    c.heads = 4;
    c.upsampler_dim = 128;
    // Scenes normalised to [-1,1]^3 sit a few units away: start the depth head near 2.4
    // (20 * sigmoid(-2)) instead of the official 9 (500 * sigmoid(-4)), which a small model
    // trained briefly from scratch would spend most of its steps unlearning.
    c.depth_far = 20.0;
    c.depth_bias = -2.0;
    c.scale_bias = -3.3;  // about a pixel wide at 64-128 px instead of 2-5 px
    c.scale_reference_height = 128;  // where it is trained
    c.rgb_from_input = true;
    return c;
  }
  if (name == "medium") {  // a default model trained on a GPU: ~10 M parameters, head dim 64
    c.embed_dim = 320;
    c.blocks = 8;
    c.heads = 5;
    c.upsampler_dim = 256;
    c.depth_far = 20.0;  // the same starting points as `mini` (see there)
    c.depth_bias = -2.0;
    c.scale_bias = -4.0;  // about a pixel wide at 256 px
    c.rgb_from_input = true;
    return c;
  }
  if (name == "tiny") {  // the official-layout parity fixture
    c.embed_dim = 128;
    c.blocks = 2;
    c.heads = 16;
    c.upsampler_dim = 64;
    return c;
  }
  fail("unknown model preset '{}' (known: {})", name, preset_names());
}

const char* ModelConfig::preset_names() { return "release, base, small, medium, mini, tiny"; }

int64_t ModelConfig::parameter_count() const {
  const int64_t D = embed_dim, p2 = static_cast<int64_t>(patch) * patch;
  int64_t n = D * image_channels * p2 + D * 6 * p2 + D;  // patch convs + cls token
  const int64_t hidden = static_cast<int64_t>(mlp_ratio) * D;
  n += blocks * (3 * D * D + D * D + 2 * D * hidden);
  for (int c : GaussianHeads::channels) {
    n += upsampler_dim * D + static_cast<int64_t>(upsampler_depth - 1) * upsampler_dim * upsampler_dim;
    n += p2 * c * upsampler_dim;
  }
  return n;
}

double ModelConfig::forward_flops(int views, int height, int width) const {
  const double D = embed_dim, p2 = static_cast<double>(patch) * patch;
  const double N = static_cast<double>(views) * (height / patch) * (width / patch);
  double f = 2 * N * D * (image_channels + 6) * p2;                       // patch embedding
  f += blocks * (2 * N * D * D * (3 + 1 + 2 * mlp_ratio) + 4 * N * N * D);  // linears + attention
  for (int c : GaussianHeads::channels)
    f += 2 * N * (D * upsampler_dim + (upsampler_depth - 1.0) * upsampler_dim * upsampler_dim +
                  upsampler_dim * p2 * c);
  return f;
}

void ModelConfig::validate() const {
  if (embed_dim <= 0 || blocks < 0 || heads <= 0 || patch <= 0 || upsampler_dim <= 0 ||
      upsampler_depth < 1 || mlp_ratio <= 0)
    fail("model config: sizes must be positive (embed_dim {}, blocks {}, heads {}, patch {}, "
         "upsampler_dim {}, upsampler_depth {})",
         embed_dim, blocks, heads, patch, upsampler_dim, upsampler_depth);
  if (embed_dim % heads != 0)
    fail("model config: embed_dim {} is not divisible by {} heads", embed_dim, heads);
  if (image_channels != 3 && image_channels != 4)
    fail("model config: image_channels must be 3 (RGB) or 4 (RGB + mask), got {}", image_channels);
  if (scale_reference_height < 0)
    fail("model config: scale_reference_height must be 0 (sizes in scene units) or a height in pixels, got {}",
         scale_reference_height);
}

nlohmann::json ModelConfig::to_json() const {
  return {{"preset", preset},
          {"embed_dim", embed_dim},
          {"depth", blocks},
          {"num_heads", heads},
          {"patch_size", patch},
          {"image_channels", image_channels},
          {"upsampler_mlp_dim", upsampler_dim},
          {"upsampler_mlp_depth", upsampler_depth},
          {"mlp_ratio", mlp_ratio},
          {"depth_near", depth_near},
          {"depth_far", depth_far},
          {"depth_bias", depth_bias},
          {"scale_bias", scale_bias},
          {"scale_min", scale_min},
          {"scale_max", scale_max},
          {"opacity_bias", opacity_bias},
          {"scale_reference_height", scale_reference_height},
          {"rgb_from_input", rgb_from_input}};
}

ModelConfig ModelConfig::from_json(const nlohmann::json& j) {
  ModelConfig c;
  auto get = [&](const char* key, auto& field) {
    if (!j.contains(key) || j[key].is_null()) return;
    try {
      field = j[key].get<std::decay_t<decltype(field)>>();
    } catch (const nlohmann::json::exception&) {
      fail("model config: {} has the wrong type ({})", key, j[key].dump());
    }
  };
  get("preset", c.preset);
  get("embed_dim", c.embed_dim);
  get("depth", c.blocks);
  get("num_heads", c.heads);
  get("patch_size", c.patch);
  get("image_channels", c.image_channels);
  get("upsampler_mlp_dim", c.upsampler_dim);
  get("upsampler_mlp_depth", c.upsampler_depth);
  get("mlp_ratio", c.mlp_ratio);
  get("depth_near", c.depth_near);
  get("depth_far", c.depth_far);
  get("depth_bias", c.depth_bias);
  get("scale_bias", c.scale_bias);
  get("scale_min", c.scale_min);
  get("scale_max", c.scale_max);
  get("opacity_bias", c.opacity_bias);
  get("scale_reference_height", c.scale_reference_height);
  get("rgb_from_input", c.rgb_from_input);
  return c;
}

}  // namespace ii
