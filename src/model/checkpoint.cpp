#include "model/checkpoint.h"

#include <spdlog/spdlog.h>

#include <regex>

#include "common/error.h"
#include "io/pth.h"
#include "tensor/tensor_file.h"

namespace ii {

namespace fs = std::filesystem;

namespace {

const char* kModules[] = {"mvencoder", "gaudecoder", "gauupsampler"};

bool starts_with(const std::string& s, const std::string& prefix) { return s.rfind(prefix, 0) == 0; }

}  // namespace

StateDict normalize_state_dict(const StateDict& raw, int* folded, StateDict* weight_norm) {
  StateDict named;
  for (const auto& [key, value] : raw) {
    std::string k = key;
    if (starts_with(k, "module.")) k = k.substr(7);
    bool model_key = false;
    for (const char* m : kModules) {
      const std::string prefix = std::string(m) + ".";
      if (!starts_with(k, prefix)) continue;
      model_key = true;
      // DDP-wrapped modules save as "<module>.module.<name>".
      if (starts_with(k, prefix + "module.")) k = prefix + k.substr(prefix.size() + 7);
    }
    // Optimiser state, epoch, extra_token_embed (parameter-free) are not model weights.
    if (model_key) named[k] = value.to(torch::kFloat32);
  }
  StateDict out;
  int count = 0;
  for (const auto& [key, value] : named) {
    const bool is_g = key.size() > 9 && key.compare(key.size() - 9, 9, ".weight_g") == 0;
    const bool is_v = key.size() > 9 && key.compare(key.size() - 9, 9, ".weight_v") == 0;
    if (!is_g && !is_v) {
      out[key] = value;
      continue;
    }
    if (weight_norm) (*weight_norm)[key] = value;
    const std::string base = key.substr(0, key.size() - 9);
    if (is_v) continue;  // handled with its g
    auto v = named.find(base + ".weight_v");
    if (v == named.end()) fail("weight-norm gain {} has no matching {}.weight_v", key, base);
    // W = g * v / ||v||, norm over every dimension but the first (PyTorch weight_norm, dim=0).
    const torch::Tensor vv = v->second;
    const torch::Tensor norms = vv.reshape({vv.size(0), -1}).norm(2, 1).reshape(value.sizes());
    out[base + ".weight"] = value * vv / norms;
    ++count;
  }
  for (const auto& [key, value] : named)
    if (key.size() > 9 && key.compare(key.size() - 9, 9, ".weight_v") == 0 &&
        !named.count(key.substr(0, key.size() - 9) + ".weight_g"))
      fail("weight-norm direction {} has no matching gain", key);
  if (folded) *folded = count;
  return out;
}

ModelConfig infer_config(const StateDict& state, const nlohmann::json& hints, const std::string& source) {
  auto get = [&](const std::string& key) -> const torch::Tensor& {
    auto it = state.find(key);
    if (it == state.end()) fail("{}: not an InstaInpaint checkpoint: no tensor {}", source, key);
    return it->second;
  };
  ModelConfig c;
  try {
    c = ModelConfig::from_json(hints);
  } catch (const Error& e) {
    fail("{}: {}", source, e.what());
  }
  const torch::Tensor& proj = get("mvencoder.patch_embed.proj.weight");
  if (proj.dim() != 4 || proj.size(2) != proj.size(3))
    fail("{}: mvencoder.patch_embed.proj.weight has an unexpected shape", source);
  c.embed_dim = static_cast<int>(proj.size(0));
  c.image_channels = static_cast<int>(proj.size(1));
  c.patch = static_cast<int>(proj.size(2));
  int blocks = 0;
  const std::regex block_re(R"(gaudecoder\.blocks\.(\d+)\..*)");
  for (const auto& kv : state) {
    std::smatch m;
    if (std::regex_match(kv.first, m, block_re)) blocks = std::max(blocks, std::stoi(m[1]) + 1);
  }
  c.blocks = blocks;
  if (blocks > 0) c.mlp_ratio = static_cast<int>(get("gaudecoder.blocks.0.mlp.fc1.weight").size(0) / c.embed_dim);
  c.upsampler_dim = static_cast<int>(get("gauupsampler.mlp_depth.0.weight").size(0));
  int layers = 0;
  while (state.count(fmt::format("gauupsampler.mlp_depth.{}.weight", 2 * layers))) ++layers;
  c.upsampler_depth = std::max(1, layers - 1);
  // The head count is not visible in shapes: it comes from the stored arguments, else the
  // official 16 (ModelConfig's default).
  c.preset = "custom";
  for (const char* name : {"release", "base", "small", "mini", "tiny"}) {
    ModelConfig p = ModelConfig::from_preset(name);
    if (p.embed_dim == c.embed_dim && p.blocks == c.blocks && p.heads == c.heads &&
        p.upsampler_dim == c.upsampler_dim && p.patch == c.patch)
      c.preset = name;
  }
  c.validate();
  return c;
}

StateDict read_safetensors_tensors(const fs::path& path) {
  StateDict out;
  for (auto& [name, t] : read_safetensors(path).tensors) out[name] = tensor_from_data(std::move(t), path);
  return out;
}

namespace {

// Key normalisation, weight-norm folding and architecture inference shared by every source.
void finish_checkpoint(Checkpoint& ck, const StateDict& raw, const nlohmann::json& hints, const fs::path& path,
                       bool keep_weight_norm) {
  ck.state = normalize_state_dict(raw, &ck.folded_weight_norms, keep_weight_norm ? &ck.weight_norm : nullptr);
  if (ck.state.empty()) fail_file(path, "holds no InstaInpaint model weights (no mvencoder/gaudecoder/gauupsampler keys)");
  ck.config = infer_config(ck.state, hints, path.string());
}

}  // namespace

namespace {

Checkpoint checkpoint_from_tensors(const StateDict& raw, const std::map<std::string, std::string>& metadata,
                                   const fs::path& path, bool keep_weight_norm) {
  Checkpoint ck;
  ck.format = "safetensors";
  ck.extra = nlohmann::json(metadata);
  nlohmann::json hints = nlohmann::json::object();
  if (auto it = metadata.find("config"); it != metadata.end()) {
    try {
      hints = nlohmann::json::parse(it->second);
    } catch (const nlohmann::json::exception& e) {
      fail_file(path, "__metadata__.config is not valid JSON: {}", e.what());
    }
  }
  finish_checkpoint(ck, raw, hints, path, keep_weight_norm);
  return ck;
}

}  // namespace

Checkpoint checkpoint_from_safetensors(SafetensorsFile file, const fs::path& path, bool keep_weight_norm) {
  StateDict raw;
  for (auto& [name, t] : file.tensors) raw[name] = tensor_from_data(std::move(t), path);
  return checkpoint_from_tensors(raw, file.metadata, path, keep_weight_norm);
}

Checkpoint read_checkpoint(const fs::path& path, bool keep_weight_norm, bool map_weights) {
  if (is_safetensors_file(path)) {
    if (!map_weights) return checkpoint_from_safetensors(read_safetensors(path), path, keep_weight_norm);
    std::map<std::string, std::string> metadata;
    const StateDict raw = map_safetensors_tensors(path, &metadata);
    return checkpoint_from_tensors(raw, metadata, path, keep_weight_norm);
  }
  Checkpoint ck;
  StateDict raw;
  nlohmann::json hints = nlohmann::json::object();
  {
    ck.format = "pth";
    const PickleValue tree = read_pth(path);
    std::map<std::string, PthTensor> tensors;
    collect_tensors(tree, "", tensors, path);
    for (const auto& [name, t] : tensors) raw[name] = tensor_from_pth(t, path);
    ck.extra = nlohmann::json::parse(extras_to_json(tree));
    // The official training arguments name the heads as `num_heads` when present.
    if (ck.extra.contains("args") && ck.extra["args"].is_object() && ck.extra["args"].contains("num_heads"))
      hints["num_heads"] = ck.extra["args"]["num_heads"];
  }
  finish_checkpoint(ck, raw, hints, path, keep_weight_norm);
  return ck;
}

Network network_from_checkpoint(const Checkpoint& ck, const std::string& source) {
  Network net(ck.config, /*initialise=*/false);
  net.load(ck.state, source);
  return net;
}

Network network_from_checkpoint(Checkpoint&& ck, const std::string& source) {
  Network net(ck.config, /*initialise=*/false);
  net.load(std::move(ck.state), source);
  return net;
}

Network load_network(const fs::path& path) {
  const Checkpoint ck = read_checkpoint(path);
  Network net = network_from_checkpoint(std::move(ck), path.string());
  spdlog::debug("{}: {} model ({} blocks, width {}), {} weight-norm pairs folded", path.string(),
                ck.config.preset, ck.config.blocks, ck.config.embed_dim, ck.folded_weight_norms);
  return net;
}

void save_safetensors_checkpoint(const fs::path& path, const Network& network, const nlohmann::json& extra_metadata) {
  std::vector<std::pair<std::string, torch::Tensor>> tensors;
  auto add = [&](const std::string& name, const torch::Tensor& t) { tensors.emplace_back(name, t.to(torch::kFloat32)); };
  for (const auto& [name, w] : network.named_parameters()) {
    // Every Linear of the decoder and upsampler is weight-normed in the official layout.
    const bool weight_normed = starts_with(name, "gaudecoder.") || starts_with(name, "gauupsampler.");
    if (!weight_normed) {
      add(name, w);
      continue;
    }
    const std::string base = name.substr(0, name.size() - 7);  // strip ".weight"
    add(base + ".weight_g", w.detach().norm(2, 1, true));
    add(base + ".weight_v", w);
  }
  std::map<std::string, std::string> metadata;
  metadata["config"] = network.config().to_json().dump();
  metadata["format"] = "instainpaint";
  for (const auto& [k, v] : extra_metadata.items()) metadata[k] = v.is_string() ? v.get<std::string>() : v.dump();
  write_tensor_file(path, tensors, metadata);
}

}  // namespace ii
