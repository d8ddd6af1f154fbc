// Reading SAM's and MobileSAM's published checkpoints into segment/sam_model.h's modules.
#include <set>

#include <fmt/ranges.h>

#include "common/error.h"
#include "segment/sam_model.h"
#include "tensor/tensor_taker.h"

namespace ii::sam {
namespace {

Linear linear(TensorTaker& t, const std::string& key, int64_t out, int64_t in, bool bias = true) {
  Linear l;
  l.weight = t.take(key + ".weight", {out, in});
  if (bias) l.bias = t.take(key + ".bias", {out});
  return l;
}
Norm norm(TensorTaker& t, const std::string& key, int64_t width, double eps) {
  return Norm{t.take(key + ".weight", {width}), t.take(key + ".bias", {width}), eps};
}
Conv conv(TensorTaker& t, const std::string& key, int64_t out, int64_t in, int64_t k, bool bias, int64_t stride,
          int64_t padding, int64_t groups = 1) {
  Conv c;
  c.weight = t.take(key + ".weight", {out, in / groups, k, k});
  if (bias) c.bias = t.take(key + ".bias", {out});
  c.stride = stride;
  c.padding = padding;
  c.groups = groups;
  return c;
}
// TinyViT's Conv2d_BN: the batch norm's running statistics folded into the convolution.
Conv conv_bn(TensorTaker& t, const std::string& key, int64_t out, int64_t in, int64_t k, int64_t stride,
             int64_t padding, int64_t groups = 1) {
  Conv c = conv(t, key + ".c", out, in, k, false, stride, padding, groups);
  const torch::Tensor gamma = t.take(key + ".bn.weight", {out}), beta = t.take(key + ".bn.bias", {out});
  const torch::Tensor mean = t.take(key + ".bn.running_mean", {out}), var = t.take(key + ".bn.running_var", {out});
  const torch::Tensor scale = gamma / torch::sqrt(var + 1e-5);
  c.weight = c.weight * scale.view({-1, 1, 1, 1});
  c.bias = beta - mean * scale;
  return c;
}
int64_t first_dim(TensorTaker& t, const std::string& key) { return t.size(t.shape(key), 0); }

// The encoders' neck from `dim` channels to the decoder's `width`.
Neck neck(TensorTaker& t, const std::string& prefix, int64_t dim, int64_t width) {
  return Neck{conv(t, prefix + "0", width, dim, 1, false, 1, 0), conv(t, prefix + "2", width, width, 3, false, 1, 1),
              norm(t, prefix + "1", width, 1e-6), norm(t, prefix + "3", width, 1e-6)};
}

VitEncoder read_vit(TensorTaker& t, int64_t width, int64_t& image_size) {
  VitEncoder e;
  const std::string p = "image_encoder.";
  const torch::Tensor patch = t.take(p + "patch_embed.proj.weight", {-1, 3, 16, 16});
  const int64_t dim = patch.size(0);
  e.patch_embed = Conv{patch, t.take(p + "patch_embed.proj.bias", {dim}), {}, {}, 16, 0, 1};
  e.pos_embed = t.take(p + "pos_embed", {1, -1, -1, dim});
  const int64_t grid = e.pos_embed.size(1);
  if (e.pos_embed.size(2) != grid) fail("{}: {}pos_embed is not square", t.file().string(), p);
  image_size = grid * 16;
  const int64_t depth = t.count(p + "blocks.", ".norm1.weight");
  if (depth == 0) fail("{}: no {}blocks.0", t.file().string(), p);
  for (int64_t i = 0; i < depth; ++i) {
    const std::string b = p + "blocks." + std::to_string(i) + ".";
    VitBlock k;
    k.norm1 = norm(t, b + "norm1", dim, 1e-6);
    k.norm2 = norm(t, b + "norm2", dim, 1e-6);
    k.qkv = linear(t, b + "attn.qkv", 3 * dim, dim);
    k.proj = linear(t, b + "attn.proj", dim, dim);
    k.rel_pos_h = t.take(b + "attn.rel_pos_h", {-1, -1});
    k.rel_pos_w = t.take(b + "attn.rel_pos_w", {k.rel_pos_h.size(0), k.rel_pos_h.size(1)});
    const int64_t head_dim = k.rel_pos_h.size(1), span = k.rel_pos_h.size(0);
    if (head_dim == 0 || dim % head_dim != 0 || span % 2 == 0)
      fail("{}: {}attn.rel_pos_h has shape {}: not (2 x window - 1, a divisor of {})", t.file().string(), b,
           shape_text(k.rel_pos_h.sizes()), dim);
    k.heads = dim / head_dim;
    const int64_t side = (span + 1) / 2;
    k.window = side == grid ? 0 : side;  // the global blocks' table spans the whole grid
    const int64_t hidden = first_dim(t, b + "mlp.lin1.weight");
    k.lin1 = linear(t, b + "mlp.lin1", hidden, dim);
    k.lin2 = linear(t, b + "mlp.lin2", dim, hidden);
    e.blocks.push_back(std::move(k));
  }
  e.neck = neck(t, p + "neck.", dim, width);
  return e;
}

// One TinyViT block of `dim` channels under key prefix `b`: its heads and window from the
// attention biases' table (heads x window²), the table expanded to every pair of window positions.
TinyVitBlock tiny_vit_block(TensorTaker& t, const std::string& b, int64_t dim) {
  TinyVitBlock k;
  const torch::Tensor biases = t.take(b + "attn.attention_biases", {-1, -1});
  k.heads = biases.size(0);
  k.window = static_cast<int64_t>(std::lround(std::sqrt(static_cast<double>(biases.size(1)))));
  if (k.heads == 0 || dim % k.heads != 0 || k.window * k.window != biases.size(1))
    fail("{}: {}attn.attention_biases has shape {}: not (heads dividing {}, window x window)",
         t.file().string(), b, shape_text(biases.sizes()), dim);
  k.key_dim = dim / k.heads;
  // Offset (|dy|, |dx|) of two window positions is entry |dy| * window + |dx| (TinyViT numbers
  // the offsets as the first position meets them).
  const torch::Tensor pos = torch::arange(k.window * k.window);
  const torch::Tensor dy = (pos.div(k.window, "floor").unsqueeze(1) - pos.div(k.window, "floor").unsqueeze(0)).abs();
  const torch::Tensor dx = (pos.remainder(k.window).unsqueeze(1) - pos.remainder(k.window).unsqueeze(0)).abs();
  k.biases = biases.index_select(1, (dy * k.window + dx).flatten()).view({k.heads, pos.size(0), pos.size(0)});
  k.attn_norm = norm(t, b + "attn.norm", dim, 1e-5);
  k.qkv = linear(t, b + "attn.qkv", 3 * dim, dim);
  k.proj = linear(t, b + "attn.proj", dim, dim);
  k.mlp_norm = norm(t, b + "mlp.norm", dim, 1e-5);
  const int64_t hidden = first_dim(t, b + "mlp.fc1.weight");
  k.fc1 = linear(t, b + "mlp.fc1", hidden, dim);
  k.fc2 = linear(t, b + "mlp.fc2", dim, hidden);
  k.local_conv = conv_bn(t, b + "local_conv", dim, dim, 3, 1, 1, dim);
  return k;
}

TinyVitEncoder read_tiny_vit(TensorTaker& t, int64_t width) {
  TinyVitEncoder e;
  const std::string p = "image_encoder.";
  const int64_t half = first_dim(t, p + "patch_embed.seq.0.c.weight");
  const int64_t dim0 = first_dim(t, p + "patch_embed.seq.2.c.weight");
  e.embed1 = conv_bn(t, p + "patch_embed.seq.0", half, 3, 3, 2, 1);
  e.embed2 = conv_bn(t, p + "patch_embed.seq.2", dim0, half, 3, 2, 1);
  int64_t n_stages = 0;
  while (t.has(p + "layers." + std::to_string(n_stages) + ".blocks.0.conv1.c.weight") ||
         t.has(p + "layers." + std::to_string(n_stages) + ".blocks.0.attn.qkv.weight"))
    ++n_stages;
  if (n_stages < 2) fail("{}: TinyViT needs a convolution stage and an attention stage ({}layers.N)", t.file().string(), p);
  int64_t dim = dim0;
  for (int64_t s = 0; s < n_stages; ++s) {
    const std::string l = p + "layers." + std::to_string(s) + ".";
    TinyVitStage stage;
    if (s == 0) {
      const int64_t n = t.count(l + "blocks.", ".conv1.c.weight");
      for (int64_t i = 0; i < n; ++i) {
        const std::string b = l + "blocks." + std::to_string(i) + ".";
        const int64_t hidden = first_dim(t, b + "conv1.c.weight");
        stage.convs.push_back(MbConv{conv_bn(t, b + "conv1", hidden, dim, 1, 1, 0),
                                     conv_bn(t, b + "conv2", hidden, hidden, 3, 1, 1, hidden),
                                     conv_bn(t, b + "conv3", dim, hidden, 1, 1, 0)});
      }
    } else {
      const int64_t n = t.count(l + "blocks.", ".attn.qkv.weight");
      if (n == 0) fail("{}: {}blocks.0.attn is missing", t.file().string(), l);
      for (int64_t i = 0; i < n; ++i) {
        const std::string b = l + "blocks." + std::to_string(i) + ".";
        stage.blocks.push_back(tiny_vit_block(t, b, dim));
      }
    }
    if (t.has(l + "downsample.conv1.c.weight")) {
      const int64_t out = first_dim(t, l + "downsample.conv1.c.weight");
      stage.has_merge = true;
      // The stride is chosen when the image's size is known (encode_tiny_vit): 2 until the
      // tokens are a 16th of the image, as the published widths give.
      stage.merge = PatchMerging{conv_bn(t, l + "downsample.conv1", out, dim, 1, 1, 0),
                                 conv_bn(t, l + "downsample.conv2", out, out, 3, 2, 1, out),
                                 conv_bn(t, l + "downsample.conv3", out, out, 1, 1, 0)};
      dim = out;
    }
    e.stages.push_back(std::move(stage));
  }
  e.neck = neck(t, p + "neck.", dim, width);
  return e;
}

Attention attention(TensorTaker& t, const std::string& key, int64_t width) {
  const int64_t inner = first_dim(t, key + ".q_proj.weight");
  if (inner % 8 != 0) fail("{}: {}.q_proj has {} outputs, not a multiple of SAM's 8 heads", t.file().string(), key, inner);
  return Attention{linear(t, key + ".q_proj", inner, width), linear(t, key + ".k_proj", inner, width),
                   linear(t, key + ".v_proj", inner, width), linear(t, key + ".out_proj", width, inner), 8};
}

std::vector<Linear> mlp(TensorTaker& t, const std::string& key, int64_t in) {
  std::vector<Linear> layers;
  const int64_t n = t.count(key + ".layers.", ".weight");
  if (n == 0) fail("{}: {}.layers.0 is missing", t.file().string(), key);
  for (int64_t i = 0; i < n; ++i) {
    const std::string k = key + ".layers." + std::to_string(i);
    const int64_t out = first_dim(t, k + ".weight");
    layers.push_back(linear(t, k, out, in));
    in = out;
  }
  return layers;
}

PromptEncoder read_prompt_encoder(TensorTaker& t, int64_t width) {
  PromptEncoder e;
  const std::string p = "prompt_encoder.";
  e.gaussian = t.take(p + "pe_layer.positional_encoding_gaussian_matrix", {2, width / 2});
  for (int i = 0; i < 4; ++i) e.point_embeddings[i] = t.take(p + "point_embeddings." + std::to_string(i) + ".weight", {1, width});
  e.not_a_point = t.take(p + "not_a_point_embed.weight", {1, width});
  e.no_mask = t.take(p + "no_mask_embed.weight", {1, width});
  const int64_t hidden = first_dim(t, p + "mask_downscaling.3.weight");
  const int64_t quarter = first_dim(t, p + "mask_downscaling.0.weight");
  e.mask_conv1 = conv(t, p + "mask_downscaling.0", quarter, 1, 2, true, 2, 0);
  e.mask_norm1 = norm(t, p + "mask_downscaling.1", quarter, 1e-6);
  e.mask_conv2 = conv(t, p + "mask_downscaling.3", hidden, quarter, 2, true, 2, 0);
  e.mask_norm2 = norm(t, p + "mask_downscaling.4", hidden, 1e-6);
  e.mask_conv3 = conv(t, p + "mask_downscaling.6", width, hidden, 1, true, 1, 0);
  return e;
}

MaskDecoder read_mask_decoder(TensorTaker& t, int64_t width) {
  MaskDecoder d;
  const std::string p = "mask_decoder.";
  const int64_t depth = t.count(p + "transformer.layers.", ".norm1.weight");
  if (depth == 0) fail("{}: {}transformer.layers.0 is missing", t.file().string(), p);
  for (int64_t i = 0; i < depth; ++i) {
    const std::string l = p + "transformer.layers." + std::to_string(i) + ".";
    TwoWayBlock b;
    b.self_attn = attention(t, l + "self_attn", width);
    b.token_to_image = attention(t, l + "cross_attn_token_to_image", width);
    b.image_to_token = attention(t, l + "cross_attn_image_to_token", width);
    b.norm1 = norm(t, l + "norm1", width, 1e-5);
    b.norm2 = norm(t, l + "norm2", width, 1e-5);
    b.norm3 = norm(t, l + "norm3", width, 1e-5);
    b.norm4 = norm(t, l + "norm4", width, 1e-5);
    const int64_t hidden = first_dim(t, l + "mlp.lin1.weight");
    b.lin1 = linear(t, l + "mlp.lin1", hidden, width);
    b.lin2 = linear(t, l + "mlp.lin2", width, hidden);
    d.blocks.push_back(std::move(b));
  }
  d.final_attn = attention(t, p + "transformer.final_attn_token_to_image", width);
  d.final_norm = norm(t, p + "transformer.norm_final_attn", width, 1e-5);
  d.iou_token = t.take(p + "iou_token.weight", {1, width});
  d.mask_tokens = t.take(p + "mask_tokens.weight", {-1, width});
  const int64_t masks = d.mask_tokens.size(0);
  if (masks < 2) fail("{}: {}mask_tokens.weight holds {} token(s); SAM has one more than its masks", t.file().string(), p, masks);
  // ConvTranspose2d weights are (in, out, k, k).
  d.upscale1 = Conv{t.take(p + "output_upscaling.0.weight", {width, width / 4, 2, 2}),
                    t.take(p + "output_upscaling.0.bias", {width / 4}), {}, {}, 2, 0, 1};
  d.upscale_norm = norm(t, p + "output_upscaling.1", width / 4, 1e-6);
  d.upscale2 = Conv{t.take(p + "output_upscaling.3.weight", {width / 4, width / 8, 2, 2}),
                    t.take(p + "output_upscaling.3.bias", {width / 8}), {}, {}, 2, 0, 1};
  for (int64_t i = 0; i < masks; ++i) {
    d.hypernetworks.push_back(mlp(t, p + "output_hypernetworks_mlps." + std::to_string(i), width));
    if (d.hypernetworks.back().back().weight.size(0) != width / 8)
      fail("{}: {}output_hypernetworks_mlps.{} ends with {} outputs, expected {}", t.file().string(), p, i,
           d.hypernetworks.back().back().weight.size(0), width / 8);
  }
  d.iou_head = mlp(t, p + "iou_prediction_head", width);
  if (d.iou_head.back().weight.size(0) != masks)
    fail("{}: {}iou_prediction_head ends with {} outputs, expected {}", t.file().string(), p,
         d.iou_head.back().weight.size(0), masks);
  return d;
}

}  // namespace

Model model_from_tensors(TensorMap tensors, const std::filesystem::path& file) {
  TensorTaker t(std::move(tensors), file, "a SAM or MobileSAM checkpoint", "SAM or MobileSAM module");
  Model m;
  if (!t.has("mask_decoder.iou_token.weight")) {
    fail("{}: not a SAM or MobileSAM checkpoint (no mask_decoder.iou_token.weight; segment-anything's "
         "sam_vit_b_01ec64.pth or MobileSAM's mobile_sam.pt are)",
         file.string());
  }
  m.width = t.size(t.shape("mask_decoder.iou_token.weight"), 1);
  if (m.width < 8 || m.width % 8 != 0) fail("{}: the decoder's width {} is not a multiple of 8", file.string(), m.width);
  if (t.has("image_encoder.patch_embed.proj.weight")) {
    m.vit = read_vit(t, m.width, m.image_size);
    m.description = fmt::format("SAM ViT ({} wide, {} blocks, {} heads)", m.vit.pos_embed.size(3), m.vit.blocks.size(),
                                m.vit.blocks[0].heads);
  } else if (t.has("image_encoder.patch_embed.seq.0.c.weight")) {
    m.tiny_vit = true;
    m.tiny = read_tiny_vit(t, m.width);
    m.image_size = 1024;  // TinyViT's forward pass ends at 64 x 64 tokens
    m.description = fmt::format("MobileSAM TinyViT ({} stages)", m.tiny.stages.size());
  } else {
    fail("{}: its image encoder is neither SAM's ViT (image_encoder.patch_embed.proj) nor MobileSAM's TinyViT "
         "(image_encoder.patch_embed.seq)",
         file.string());
  }
  m.embedding_size = m.image_size / 16;
  m.prompt = read_prompt_encoder(t, m.width);
  m.decoder = read_mask_decoder(t, m.width);
  t.check_all_used({"image_encoder.norm_head.", "image_encoder.head.", "attention_bias_idxs", "num_batches_tracked"});
  return m;
}

Model read_model(const std::filesystem::path& path) {
  if (!std::filesystem::is_regular_file(path)) fail("{}: no such segmentation model file", path.string());
  return model_from_tensors(read_tensor_file(path), path);
}

}  // namespace ii::sam
