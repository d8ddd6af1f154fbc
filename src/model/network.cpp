#include "model/network.h"

#include <cmath>
#include <set>

#include <fmt/ranges.h>

#include "common/error.h"
#include "common/stopwatch.h"
#include "model/attention.h"
#include "model/layer_norm.h"

namespace ii {

const char* precision_name(Precision p) {
  return p == Precision::Float32 ? "fp32" : "bf16";
}

Precision default_cpu_precision() {
  // Without native bf16 dot products, bf16 matrix products are emulated and slower than fp32.
  return cpu_features().native_bf16() ? Precision::BFloat16 : Precision::Float32;
}

void StageProfile::add(const std::string& stage, double milliseconds) {
  for (auto& [name, total] : ms)
    if (name == stage) {
      total += milliseconds;
      return;
    }
  ms.emplace_back(stage, milliseconds);
}

double StageProfile::total() const {
  double sum = 0;
  for (const auto& entry : ms) sum += entry.second;
  return sum;
}

namespace {

// Marks the end of a stage: the time since the previous mark goes to the profile, if any.
class StageClock {
 public:
  explicit StageClock(StageProfile* profile) : profile_(profile) {}
  void operator()(const char* stage) {
    if (profile_) profile_->add(stage, watch_.lap());
  }
  void skip() { watch_.lap(); }  // time measured elsewhere

 private:
  StageProfile* profile_;
  Stopwatch watch_;
};

}  // namespace

torch::Tensor& Network::add(const std::string& name, torch::Tensor value) {
  params_.emplace_back(name, std::move(value));
  return params_.back().second;
}

Network::Network(const ModelConfig& config, bool initialise) : config_(config) {
  config_.validate();
  torch::NoGradGuard no_grad;
  const int64_t D = config_.embed_dim, p = config_.patch, U = config_.upsampler_dim;
  auto normal = [&](std::vector<int64_t> shape, double std) {
    return initialise ? torch::randn(shape) * std : torch::empty(shape);
  };
  // Zero-initialised Plücker branch as in the official code; small normal elsewhere.
  proj_ = add("mvencoder.patch_embed.proj.weight", normal({D, config_.image_channels, p, p}, 0.02));
  proj_plucker_ = add("mvencoder.patch_embed.proj_plucker.weight", normal({D, 6, p, p}, 0.0));
  cls_token_ = add("mvencoder.cls_token", normal({1, 1, D}, 0.02));
  for (int b = 0; b < config_.blocks; ++b) {
    const std::string prefix = fmt::format("gaudecoder.blocks.{}.", b);
    Block blk;
    blk.qkv = add(prefix + "attn.qkv.weight", normal({3 * D, D}, 0.02));
    blk.proj = add(prefix + "attn.proj.weight", normal({D, D}, 0.02 / std::sqrt(2.0 * std::max(1, config_.blocks))));
    blk.fc1 = add(prefix + "mlp.fc1.weight", normal({config_.mlp_ratio * D, D}, 0.02));
    blk.fc2 = add(prefix + "mlp.fc2.weight", normal({D, config_.mlp_ratio * D}, 0.02 / std::sqrt(2.0 * std::max(1, config_.blocks))));
    blocks_.push_back(blk);
  }
  for (int h = 0; h < GaussianHeads::count; ++h) {
    Head head;
    int64_t in = D;
    for (int l = 0; l < config_.upsampler_depth; ++l) {
      head.layers.push_back(add(fmt::format("gauupsampler.mlp_{}.{}.weight", GaussianHeads::names[h], 2 * l),
                                normal({U, in}, 0.02)));
      in = U;
    }
    head.layers.push_back(add(fmt::format("gauupsampler.mlp_{}.{}.weight", GaussianHeads::names[h], 2 * config_.upsampler_depth),
                              normal({p * p * GaussianHeads::channels[h], in}, 0.002)));
    heads_.push_back(head);
  }
}

std::vector<torch::Tensor> Network::parameters() const {
  std::vector<torch::Tensor> out;
  for (const auto& kv : params_) out.push_back(kv.second);
  return out;
}

void Network::check_fits(const std::map<std::string, torch::Tensor>& state, const std::string& source) const {
  std::vector<std::string> missing, wrong_shape;
  std::set<std::string> used;
  for (auto& [name, param] : params_) {
    auto it = state.find(name);
    if (it == state.end()) {
      missing.push_back(name);
      continue;
    }
    used.insert(name);
    if (it->second.sizes() != param.sizes()) {
      wrong_shape.push_back(fmt::format("{} has shape [{}], the {} model needs [{}]", name,
                                        fmt::join(it->second.sizes(), ", "), config_.preset,
                                        fmt::join(param.sizes(), ", ")));
      continue;
    }
  }
  std::vector<std::string> unexpected;
  for (const auto& kv : state)
    if (!used.count(kv.first)) unexpected.push_back(kv.first);
  if (!missing.empty() || !wrong_shape.empty() || !unexpected.empty()) {
    std::string msg = fmt::format("{}: checkpoint does not fit the model architecture", source);
    auto list = [&](const char* what, const std::vector<std::string>& items) {
      if (items.empty()) return;
      msg += fmt::format("\n  {} ({}): ", what, items.size());
      for (size_t i = 0; i < std::min<size_t>(items.size(), 5); ++i) msg += (i ? ", " : "") + items[i];
      if (items.size() > 5) msg += ", ...";
    };
    list("wrong shape", wrong_shape);
    list("missing", missing);
    list("unexpected", unexpected);
    throw Error(msg);
  }
}

void Network::load(const std::map<std::string, torch::Tensor>& state, const std::string& source) {
  check_fits(state, source);
  torch::NoGradGuard no_grad;
  for (auto& [name, param] : params_) param.copy_(state.at(name));
  clear_weight_caches();
}

void Network::load(std::map<std::string, torch::Tensor>&& state, const std::string& source) {
  check_fits(state, source);
  std::vector<torch::Tensor> values;
  for (const auto& [name, param] : params_) {
    torch::Tensor& t = state.at(name);
    const bool as_is = t.scalar_type() == param.scalar_type() && t.device() == param.device() && t.is_contiguous();
    values.push_back((as_is ? std::move(t) : t.to(param.options()).contiguous()).requires_grad_(param.requires_grad()));
  }
  set_parameters(values);
}

void Network::to(const torch::Device& device) {
  std::vector<torch::Tensor> moved;
  for (const auto& kv : params_) moved.push_back(kv.second.to(device));
  set_parameters(moved);
}

void Network::set_parameters(const std::vector<torch::Tensor>& values) {
  if (values.size() != params_.size())
    fail("set_parameters: {} tensors given, the network has {}", values.size(), params_.size());
  for (size_t k = 0; k < values.size(); ++k)
    if (values[k].sizes() != params_[k].second.sizes())
      fail("set_parameters: {} has shape [{}], needs [{}]", params_[k].first, fmt::join(values[k].sizes(), ", "),
           fmt::join(params_[k].second.sizes(), ", "));
  for (size_t k = 0; k < values.size(); ++k) params_[k].second = values[k];
  // Re-point the structured views at the new tensors.
  size_t i = 0;
  proj_ = params_[i++].second;
  proj_plucker_ = params_[i++].second;
  cls_token_ = params_[i++].second;
  for (Block& b : blocks_) {
    b.qkv = params_[i++].second;
    b.proj = params_[i++].second;
    b.fc1 = params_[i++].second;
    b.fc2 = params_[i++].second;
  }
  for (Head& h : heads_)
    for (torch::Tensor& l : h.layers) l = params_[i++].second;
  clear_weight_caches();
}

void Network::set_requires_grad(bool requires_grad) {
  for (auto& kv : params_) kv.second.set_requires_grad(requires_grad);
  clear_weight_caches();
}

void Network::clear_weight_caches() {
  bf16_cache_.clear();
  fused_head_input_ = torch::Tensor();
}

torch::Tensor Network::fused_head_input_weight() const {
  std::vector<torch::Tensor> firsts;
  for (const Head& h : heads_) firsts.push_back(h.layers.front());
  // Training binds weights with autograd history each step: concatenate afresh so gradients
  // reach them. Inference concatenates once.
  if (firsts.front().requires_grad()) return torch::cat(firsts);
  if (!fused_head_input_.defined()) fused_head_input_ = torch::cat(firsts);
  return fused_head_input_;
}

torch::Tensor Network::weight_for(const torch::Tensor& weight, Precision precision) const {
  if (precision == Precision::Float32 || weight.requires_grad() || !execution_.cached_weights) {
    return precision == Precision::Float32 ? weight : weight.to(torch::kBFloat16);
  }
  // Inference: convert each weight to bf16 once and keep it.
  auto it = bf16_cache_.find(weight.data_ptr());
  if (it == bf16_cache_.end()) it = bf16_cache_.emplace(weight.data_ptr(), weight.to(torch::kBFloat16)).first;
  return it->second;
}

torch::Tensor Network::linear(const torch::Tensor& x, const torch::Tensor& weight, Precision precision) const {
  if (precision == Precision::Float32) return torch::matmul(x, weight.t());
  return torch::matmul(x.to(torch::kBFloat16), weight_for(weight, precision).t());
}

torch::Tensor unpatchify(const torch::Tensor& x, int views, int h, int w, int patch, int channels) {
  const int64_t B = x.size(0);
  // Element (py*p + px)*C + c of token (v, a, b) is channel c of pixel (a*p + py, b*p + px).
  return x.reshape({B, views, h, w, patch, patch, channels})
      .permute({0, 1, 6, 2, 4, 3, 5})
      .reshape({B, views, channels, h * patch, w * patch});
}

namespace {

// One pre-norm transformer block (spec §1.2 step 6). `in`: the residual stream (float) and
// its layer norm in the compute dtype, the dtype of the Linear weights. Returns the block's
// output and, with `norm_output`, its layer norm (the next block's or the heads' input), each
// residual add fused with the layer norm that follows it (`fused_norms`, model/layer_norm.h).
AddNorm transformer_block(const AddNorm& in, const torch::Tensor& qkv_w, const torch::Tensor& proj_w,
                          const torch::Tensor& fc1_w, const torch::Tensor& fc2_w, int64_t heads, double ln_eps,
                          AttentionForm form, bool fused_norms, bool norm_output, StageProfile* profile = nullptr) {
  const torch::Tensor& x = in.sum;
  const int64_t B = x.size(0), N = x.size(1), D = x.size(2), hd = D / heads;
  const auto dtype = qkv_w.scalar_type();
  StageClock mark(profile);
  const torch::Tensor qkv = torch::matmul(in.normed, qkv_w.t())
                                .reshape({B, N, 3, heads, hd})
                                .permute({2, 0, 3, 1, 4});  // (3, B, heads, N, hd)
  mark("linear qkv");
  const torch::Tensor a = attention(qkv[0], qkv[1], qkv[2], form).permute({0, 2, 1, 3}).reshape({B, N, D});
  mark("attention");
  const torch::Tensor projected = torch::matmul(a, proj_w.t());
  mark("linear proj");
  const AddNorm mid = add_layer_norm(x, projected, ln_eps, dtype, fused_norms);
  mark("residual add + layer norm");
  const torch::Tensor hidden = torch::matmul(mid.normed, fc1_w.t());
  mark("linear fc1");
  const torch::Tensor activated = torch::gelu(hidden);
  mark("gelu");
  const torch::Tensor out = torch::matmul(activated, fc2_w.t());
  mark("linear fc2");
  AddNorm result = norm_output ? add_layer_norm(mid.sum, out, ln_eps, dtype, fused_norms)
                               : AddNorm{mid.sum + out.to(torch::kFloat32), {}};
  mark("residual add + layer norm");
  return result;
}

// A block that keeps only its inputs for the backward pass and runs itself again there
// (activation checkpointing): memory per block drops from all activations to one (B, N, D).
struct RecomputedBlock : torch::autograd::Function<RecomputedBlock> {
  static torch::Tensor run(const torch::Tensor& x, const std::vector<torch::Tensor>& w, int64_t heads, double ln_eps,
                           int64_t form, bool bf16) {
    auto cast = [&](const torch::Tensor& t) { return bf16 ? t.to(torch::kBFloat16) : t; };
    const auto dtype = bf16 ? torch::kBFloat16 : torch::kFloat32;
    // The forward pass (no grad mode) and the recomputation (grad mode) must compute the same:
    // on the CPU both use the LibTorch forms, as the fused CPU kernels have no backward pass.
    AttentionForm attention_form = static_cast<AttentionForm>(form);
    if (attention_form == AttentionForm::Fastest && !x.is_cuda()) attention_form = AttentionForm::Chunked;
    return transformer_block(add_layer_norm(x, {}, ln_eps, dtype, false), cast(w[0]), cast(w[1]), cast(w[2]),
                             cast(w[3]), heads, ln_eps, attention_form, false, false)
        .sum;
  }
  static torch::Tensor forward(torch::autograd::AutogradContext* ctx, const torch::Tensor& x, const torch::Tensor& qkv,
                               const torch::Tensor& proj, const torch::Tensor& fc1, const torch::Tensor& fc2,
                               int64_t heads, double ln_eps, int64_t form, bool bf16) {
    ctx->save_for_backward({x, qkv, proj, fc1, fc2});
    ctx->saved_data["heads"] = heads;
    ctx->saved_data["ln_eps"] = ln_eps;
    ctx->saved_data["form"] = form;
    ctx->saved_data["bf16"] = bf16;
    return run(x, {qkv, proj, fc1, fc2}, heads, ln_eps, form, bf16);
  }
  static torch::autograd::variable_list backward(torch::autograd::AutogradContext* ctx,
                                                 torch::autograd::variable_list grad_output) {
    std::vector<torch::Tensor> inputs;
    for (const torch::Tensor& t : ctx->get_saved_variables()) inputs.push_back(t.detach().requires_grad_(true));
    torch::Tensor y;
    {
      torch::AutoGradMode enable_grad(true);
      y = run(inputs[0], {inputs[1], inputs[2], inputs[3], inputs[4]}, ctx->saved_data["heads"].toInt(),
              ctx->saved_data["ln_eps"].toDouble(), ctx->saved_data["form"].toInt(), ctx->saved_data["bf16"].toBool());
    }
    torch::autograd::variable_list g = torch::autograd::grad({y}, inputs, {grad_output[0]});
    return {g[0], g[1], g[2], g[3], g[4], {}, {}, {}, {}};
  }
};

}  // namespace

NetworkOutput Network::forward(const torch::Tensor& images, const torch::Tensor& plucker,
                               const torch::Tensor& rays_o, const torch::Tensor& rays_d_un,
                               Precision precision) const {
  const int64_t B = images.size(0), V = images.size(1), C = images.size(2);
  const int64_t H = images.size(3), W = images.size(4);
  const int p = config_.patch;
  const int64_t D = config_.embed_dim;
  if (C != config_.image_channels)
    fail("the model takes {} image channels, the input has {}", config_.image_channels, C);
  if (H % p != 0 || W % p != 0)
    fail("input size {}x{} is not a multiple of the patch size {}", W, H, p);
  const int64_t h = H / p, w = W / p, hw = h * w;
  const auto dtype = precision == Precision::Float32 ? torch::kFloat32 : torch::kBFloat16;
  StageClock mark(profile_);

  // Patch embedding: a stride-p convolution is a matrix product over flattened patches.
  auto patches = [&](const torch::Tensor& t, int64_t channels) {
    return t.reshape({B * V, channels, h, p, w, p}).permute({0, 2, 4, 1, 3, 5}).reshape({B * V, hw, channels * p * p});
  };
  torch::Tensor tokens =
      torch::matmul(patches(images, C).to(dtype), weight_for(proj_, precision).reshape({D, -1}).t()) +
      torch::matmul(patches(plucker, 6).to(dtype), weight_for(proj_plucker_, precision).reshape({D, -1}).t());
  // Encoder norm per token (the cls token the official code prepends is normalised on its
  // own and dropped, so it cannot change any output).
  NetworkOutput out;
  out.encoder_tokens = torch::layer_norm(tokens.to(torch::kFloat32), {D}, {}, {}, config_.encoder_ln_eps);

  torch::Tensor x = out.encoder_tokens.reshape({B, V * hw, D});
  mark("patch embedding");
  torch::Tensor normed;  // layer_norm(x) after the blocks, the heads' input
  if (checkpoint_blocks_ && torch::GradMode::is_enabled()) {
    for (const Block& blk : blocks_)
      x = RecomputedBlock::apply(x, blk.qkv, blk.proj, blk.fc1, blk.fc2, static_cast<int64_t>(config_.heads),
                                 config_.ln_eps, static_cast<int64_t>(execution_.attention),
                                 precision != Precision::Float32);
    normed = add_layer_norm(x, {}, config_.ln_eps, dtype).normed;
  } else {
    AddNorm state = add_layer_norm(x, {}, config_.ln_eps, dtype, execution_.fused_norms);
    mark("residual add + layer norm");
    for (const Block& blk : blocks_)
      state = transformer_block(state, weight_for(blk.qkv, precision), weight_for(blk.proj, precision),
                                weight_for(blk.fc1, precision), weight_for(blk.fc2, precision), config_.heads,
                                config_.ln_eps, execution_.attention, execution_.fused_norms, true, profile_);
    x = state.sum;
    normed = state.normed;
  }
  out.transformer_tokens = x;
  mark.skip();  // the blocks mark their own stages

  // The five heads read the same tokens: their first Linears run as one matrix product.
  const torch::Tensor first = execution_.fused_heads ? linear(normed, fused_head_input_weight(), precision)
                                                     : torch::Tensor();
  std::vector<torch::Tensor> raw;
  int64_t offset = 0;
  for (int k = 0; k < GaussianHeads::count; ++k) {
    const auto& layers = heads_[k].layers;
    const int64_t width = layers.front().size(0);
    torch::Tensor y = first.defined() ? first.narrow(-1, offset, width) : linear(normed, layers.front(), precision);
    offset += width;
    for (size_t l = 1; l < layers.size(); ++l) y = linear(torch::gelu(y), layers[l], precision);
    raw.push_back(unpatchify(y.to(torch::kFloat32), static_cast<int>(V), static_cast<int>(h), static_cast<int>(w), p,
                             GaussianHeads::channels[k]));
  }
  mark("gaussian heads");

  GaussianMaps& g = out.gaussians;
  const torch::Tensor s = torch::sigmoid(raw[0] + config_.depth_bias);
  g.depth = config_.depth_near * (1.0 - s) + config_.depth_far * s;
  // Input RGB is in [-1,1], splat colours in [0,1] (spec §3.3).
  g.rgb = config_.rgb_from_input ? raw[1] + (images.slice(2, 0, 3).to(torch::kFloat32) + 1.0) * 0.5 : raw[1];
  g.opacity = torch::sigmoid(raw[2] + config_.opacity_bias);
  g.scale = torch::clamp(torch::exp(raw[3] + config_.scale_bias), config_.scale_min, config_.scale_max);
  if (config_.scale_reference_height > 0 && H > config_.scale_reference_height)
    g.scale = g.scale * (static_cast<double>(config_.scale_reference_height) / H);
  // The norm over the 4 quaternion channels as a sum of squares: LibTorch 1.13's norm() over
  // that outer dimension took 340 ms at 4 x 904 x 512 on 2 cores, the sum 10 ms or less.
  g.rotation = raw[4] / torch::clamp_min((raw[4] * raw[4]).sum(2, true).sqrt(), 1e-5);
  // xyz = o + depth * d_un, with rays (B, V, H, W, 3) -> channel-first.
  const torch::Tensor o = rays_o.permute({0, 1, 4, 2, 3});
  const torch::Tensor du = rays_d_un.permute({0, 1, 4, 2, 3});
  g.xyz = o + g.depth * du;
  mark("gaussian activations");
  return out;
}

}  // namespace ii
