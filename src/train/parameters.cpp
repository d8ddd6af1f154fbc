#include "train/parameters.h"

#include <set>

#include <fmt/ranges.h>

#include "common/error.h"

namespace ii {

namespace {

bool weight_normed(const std::string& name) {
  // Every Linear of the decoder and the upsampler is weight-normed in the official layout.
  return name.rfind("gaudecoder.", 0) == 0 || name.rfind("gauupsampler.", 0) == 0;
}

std::string layer_of(const std::string& weight_name) { return weight_name.substr(0, weight_name.size() - 7); }

}  // namespace

TrainableParameters::TrainableParameters(const Network& network) {
  torch::NoGradGuard no_grad;
  auto add = [&](const std::string& name, const torch::Tensor& value) {
    names_.push_back(name);
    tensors_.push_back(value.detach().clone().set_requires_grad(true));
    return static_cast<int>(tensors_.size()) - 1;
  };
  for (const auto& [name, w] : network.named_parameters()) {
    Source s;
    if (weight_normed(name)) {
      s.g = add(layer_of(name) + ".weight_g", w.norm(2, 1, true));
      s.v = add(layer_of(name) + ".weight_v", w);
    } else {
      s.plain = add(name, w);
    }
    sources_.push_back(s);
  }
}

std::vector<torch::Tensor> TrainableParameters::network_weights() const {
  std::vector<torch::Tensor> out;
  out.reserve(sources_.size());
  for (const Source& s : sources_) {
    if (s.plain >= 0) {
      out.push_back(tensors_[s.plain]);
    } else {
      const torch::Tensor& v = tensors_[s.v];
      out.push_back(tensors_[s.g] * v / v.norm(2, 1, true));
    }
  }
  return out;
}

void TrainableParameters::bind(Network& network) const { network.set_parameters(network_weights()); }

void TrainableParameters::load(const StateDict& state, const std::string& source) {
  std::vector<std::string> missing, wrong, unexpected;
  std::set<std::string> known(names_.begin(), names_.end());
  for (size_t i = 0; i < names_.size(); ++i) {
    auto it = state.find(names_[i]);
    if (it == state.end())
      missing.push_back(names_[i]);
    else if (it->second.sizes() != tensors_[i].sizes())
      wrong.push_back(fmt::format("{} [{}] (needs [{}])", names_[i], fmt::join(it->second.sizes(), ", "),
                                  fmt::join(tensors_[i].sizes(), ", ")));
  }
  for (const auto& kv : state)
    if (!known.count(kv.first)) unexpected.push_back(kv.first);
  if (!missing.empty() || !wrong.empty() || !unexpected.empty()) {
    auto list = [](const std::vector<std::string>& v) {
      std::string s;
      for (size_t i = 0; i < std::min<size_t>(v.size(), 5); ++i) s += (i ? ", " : "") + v[i];
      return v.size() > 5 ? s + ", ..." : s;
    };
    std::string msg = fmt::format("{}: the training state does not fit the model", source);
    if (!wrong.empty()) msg += fmt::format("\n  wrong shape ({}): {}", wrong.size(), list(wrong));
    if (!missing.empty()) msg += fmt::format("\n  missing ({}): {}", missing.size(), list(missing));
    if (!unexpected.empty()) msg += fmt::format("\n  unexpected ({}): {}", unexpected.size(), list(unexpected));
    throw Error(msg);
  }
  torch::NoGradGuard no_grad;
  for (size_t i = 0; i < names_.size(); ++i) tensors_[i].copy_(state.at(names_[i]));
}

int TrainableParameters::load_weight_norm(const StateDict& pairs, const std::string& source) {
  torch::NoGradGuard no_grad;
  int layers = 0;
  for (const Source& s : sources_) {
    if (s.plain >= 0) continue;
    auto g = pairs.find(names_[s.g]), v = pairs.find(names_[s.v]);
    if (g == pairs.end() || v == pairs.end()) continue;
    if (g->second.sizes() != tensors_[s.g].sizes() || v->second.sizes() != tensors_[s.v].sizes())
      fail("{}: {} / {} do not have the model's shapes", source, names_[s.g], names_[s.v]);
    tensors_[s.g].copy_(g->second);
    tensors_[s.v].copy_(v->second);
    ++layers;
  }
  return layers;
}

void TrainableParameters::to(const torch::Device& device) {
  torch::NoGradGuard no_grad;
  for (torch::Tensor& t : tensors_) t = t.to(device).detach().set_requires_grad(true);
}

StateDict expand_image_channels(StateDict state) {
  const std::string key = "mvencoder.patch_embed.proj.weight";
  auto it = state.find(key);
  if (it == state.end()) fail("cannot expand image channels: no {}", key);
  const torch::Tensor w = it->second;
  if (w.size(1) == 4) return state;
  if (w.size(1) != 3) fail("cannot expand image channels: {} has {} input channels (3 or 4 expected)", key, w.size(1));
  it->second = torch::cat({w, w.mean(1, /*keepdim=*/true)}, 1);
  return state;
}

}  // namespace ii
