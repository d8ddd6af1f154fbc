#pragma once
// SAM's and MobileSAM's modules as plain tensors under their published names (segment/segmenter.h
// is the public side): the image encoders (SAM's ViT with windowed and global attention and
// decomposed relative positions; MobileSAM's TinyViT with its convolution stage, windowed
// attention with learned offset biases and patch merging), the prompt encoder and the two-way
// mask decoder. Shapes come from the file: the widths, depths, heads (from the relative-position
// and bias tables), windows and the image size. Batch norms are folded into their convolutions.
#include <filesystem>
#include <string>
#include <vector>

#include "common/torch.h"
#include "tensor/tensor_file.h"

namespace ii::sam {

// A layer's weights in bf16 too (`half_weight`, `half_bias`, defined when the encoder runs in
// bf16): the product then takes bf16 inputs (oneDNN's kernels, AMX where the CPU has it) and
// returns float; norms, softmax and residuals stay float.
struct Linear {
  torch::Tensor weight, bias;  // bias may be undefined
  torch::Tensor half_weight, half_bias;
  torch::Tensor operator()(const torch::Tensor& x) const;
};
struct Norm {  // LayerNorm over the last dimension, or LayerNorm2d over channels
  torch::Tensor weight, bias;
  double eps = 1e-5;
  torch::Tensor operator()(const torch::Tensor& x) const;
  torch::Tensor channels(const torch::Tensor& x) const;  // (B, C, H, W), SAM's LayerNorm2d
};
// Attention's products of activations, in bf16 when the model runs so (float results).
struct Products {
  bool bf16 = false;
  torch::Tensor matmul(const torch::Tensor& a, const torch::Tensor& b) const;
};
struct Conv {
  torch::Tensor weight, bias;
  torch::Tensor half_weight, half_bias;
  int64_t stride = 1, padding = 0, groups = 1;
  torch::Tensor operator()(const torch::Tensor& x) const;
};

// Both encoders end in the same neck: 1 x 1 convolution, LayerNorm2d, 3 x 3 convolution, LayerNorm2d.
struct Neck {
  Conv conv1, conv2;
  Norm norm1, norm2;
  torch::Tensor operator()(const torch::Tensor& x) const;
};

// ---- SAM's ViT ----
struct VitBlock {
  Norm norm1, norm2;
  Linear qkv, proj, lin1, lin2;
  torch::Tensor rel_pos_h, rel_pos_w;
  int64_t heads = 0, window = 0;  // window 0: global attention
  Products products;
};
struct VitEncoder {
  Conv patch_embed;  // 16 x 16, stride 16
  torch::Tensor pos_embed;  // (1, G, G, E)
  std::vector<VitBlock> blocks;
  Neck neck;
};

// ---- MobileSAM's TinyViT ----
struct MbConv {
  Conv conv1, conv2, conv3;
};
struct TinyVitBlock {
  Norm attn_norm, mlp_norm;
  Linear qkv, proj, fc1, fc2;
  torch::Tensor biases;  // (heads, N, N): the learned bias of each offset, expanded
  int64_t heads = 0, key_dim = 0, window = 0;
  Conv local_conv;
  Products products;
};
struct PatchMerging {
  Conv conv1, conv2, conv3;
};
struct TinyVitStage {
  std::vector<MbConv> convs;          // the first stage
  std::vector<TinyVitBlock> blocks;   // the others
  bool has_merge = false;
  PatchMerging merge;
};
struct TinyVitEncoder {
  Conv embed1, embed2;
  std::vector<TinyVitStage> stages;
  Neck neck;
};

// ---- prompts and masks ----
struct PromptEncoder {
  torch::Tensor gaussian;  // (2, D/2)
  torch::Tensor point_embeddings[4], not_a_point, no_mask;  // (1, D)
  Conv mask_conv1, mask_conv2, mask_conv3;
  Norm mask_norm1, mask_norm2;
};
struct Attention {
  Linear q, k, v, out;
  int64_t heads = 8;
  Products products;
  torch::Tensor operator()(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v) const;
};
struct TwoWayBlock {
  Attention self_attn, token_to_image, image_to_token;
  Norm norm1, norm2, norm3, norm4;
  Linear lin1, lin2;
};
struct MaskDecoder {
  std::vector<TwoWayBlock> blocks;
  Attention final_attn;
  Norm final_norm;
  torch::Tensor iou_token, mask_tokens;  // (1, D), (M, D)
  Conv upscale1, upscale2;               // transposed convolutions, 2 x 2 stride 2
  Norm upscale_norm;
  std::vector<std::vector<Linear>> hypernetworks;  // one MLP per mask token
  std::vector<Linear> iou_head;
};

struct Model {
  bool tiny_vit = false;
  VitEncoder vit;
  TinyVitEncoder tiny;
  PromptEncoder prompt;
  MaskDecoder decoder;
  int64_t image_size = 1024;       // the encoder's square input
  int64_t embedding_size = 64;     // the image embedding's side
  int64_t width = 256;             // prompt and decoder width
  torch::Tensor dense_pe;          // (1, D, G, G): the prompt encoder's encoding of every grid cell
  bool bf16 = false;
  std::string description;
};

// Reads a SAM (ViT-B/L/H) or MobileSAM checkpoint (.pth/.pt through the restricted reader, or
// safetensors); an unknown layout, a missing, surplus or wrong-shaped tensor is an Error naming
// the file and the key.
Model read_model(const std::filesystem::path& path);
Model model_from_tensors(TensorMap tensors, const std::filesystem::path& file);

// Every product of the model in bf16 with float results (Linear's and Conv's bf16 copies,
// attention's products); the decoder's transposed convolutions and the mask products stay float.
void use_bf16(Model& m);

// (1, 3, S, S) normalised and padded image -> (1, D, G, G) embedding.
torch::Tensor encode_vit(const VitEncoder& e, const torch::Tensor& image);
torch::Tensor encode_tiny_vit(const TinyVitEncoder& e, const torch::Tensor& image, int64_t image_size);

}  // namespace ii::sam
