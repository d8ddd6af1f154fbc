#include "eval/lpips.h"

#include <torch/nn/functional.h>
#include <algorithm>
#include <cstdlib>
#include <limits>

#include <fmt/ranges.h>

#include "common/error.h"
#include "eval/weights.h"

namespace ii {

namespace fs = std::filesystem;
namespace F = torch::nn::functional;

namespace {

// torchvision `features` layers: index, in/out channels, kernel, stride, padding.
struct ConvSpec {
  int index;
  int64_t in, out, kernel, stride, padding;
};
struct StageSpec {
  int64_t pool_kernel, pool_stride;  // max pool before the stage's convolutions (0 = none)
  std::vector<ConvSpec> convs;
};

// VGG16 stages end at relu1_2, relu2_2, relu3_3, relu4_3, relu5_3.
const std::vector<StageSpec>& vgg_spec() {
  static const std::vector<StageSpec> spec = {
      {0, 0, {{0, 3, 64, 3, 1, 1}, {2, 64, 64, 3, 1, 1}}},
      {2, 2, {{5, 64, 128, 3, 1, 1}, {7, 128, 128, 3, 1, 1}}},
      {2, 2, {{10, 128, 256, 3, 1, 1}, {12, 256, 256, 3, 1, 1}, {14, 256, 256, 3, 1, 1}}},
      {2, 2, {{17, 256, 512, 3, 1, 1}, {19, 512, 512, 3, 1, 1}, {21, 512, 512, 3, 1, 1}}},
      {2, 2, {{24, 512, 512, 3, 1, 1}, {26, 512, 512, 3, 1, 1}, {28, 512, 512, 3, 1, 1}}},
  };
  return spec;
}

// AlexNet stages end at relu1 .. relu5.
const std::vector<StageSpec>& alex_spec() {
  static const std::vector<StageSpec> spec = {
      {0, 0, {{0, 3, 64, 11, 4, 2}}},   {3, 2, {{3, 64, 192, 5, 1, 2}}},   {3, 2, {{6, 192, 384, 3, 1, 1}}},
      {0, 0, {{8, 384, 256, 3, 1, 1}}}, {0, 0, {{10, 256, 256, 3, 1, 1}}},
  };
  return spec;
}

const std::vector<StageSpec>& spec_of(LpipsNet net) { return net == LpipsNet::vgg ? vgg_spec() : alex_spec(); }

const char* torchvision_url(LpipsNet net) {
  return net == LpipsNet::vgg ? "https://download.pytorch.org/models/vgg16-397923af.pth"
                              : "https://download.pytorch.org/models/alexnet-owt-7be5be79.pth";
}

// (N, 3, H, W) or (3, H, W) float.
torch::Tensor as_image_batch(const torch::Tensor& t, const char* name) {
  if (!t.defined()) fail("lpips: {} is undefined", name);
  torch::Tensor x = t.dim() == 3 ? t.unsqueeze(0) : t;
  if (x.dim() != 4 || x.size(1) != 3)
    fail("lpips: {} must be (N, 3, H, W) or (3, H, W), got shape [{}]", name, fmt::join(t.sizes(), ", "));
  if (!x.is_floating_point()) fail("lpips: {} must be floating point", name);
  return x;
}

// Unit length along channels; the norm is clamped from below so that an all-zero feature
// vector gets a zero (not NaN) gradient, with the same value as upstream's x / (|x| + 1e-10).
torch::Tensor normalize_channels(const torch::Tensor& x) {
  const torch::Tensor norm = torch::sqrt(x.pow(2).sum(1, /*keepdim=*/true).clamp_min(1e-20));
  return x / (norm + 1e-10);
}

}  // namespace

const char* lpips_net_name(LpipsNet net) { return net == LpipsNet::vgg ? "vgg" : "alex"; }

LpipsNet parse_lpips_net(const std::string& name) {
  if (name == "vgg") return LpipsNet::vgg;
  if (name == "alex") return LpipsNet::alex;
  fail("unknown LPIPS network '{}' (expected vgg or alex)", name);
}

const char* lpips_backbone_env_var(LpipsNet net) {
  return net == LpipsNet::vgg ? "INSTAINPAINT_LPIPS_VGG" : "INSTAINPAINT_LPIPS_ALEX";
}

const char* lpips_backbone_file_name(LpipsNet net) {
  return net == LpipsNet::vgg ? "vgg16-397923af.pth" : "alexnet-owt-7be5be79.pth";
}

std::vector<int64_t> lpips_stage_channels(LpipsNet net) {
  std::vector<int64_t> out;
  for (const StageSpec& s : spec_of(net)) out.push_back(s.convs.back().out);
  return out;
}

std::optional<fs::path> lpips_backbone_path(LpipsNet net, const std::optional<fs::path>& explicit_path) {
  if (explicit_path) {
    if (!fs::is_regular_file(*explicit_path))
      fail_file(*explicit_path, "no such file (LPIPS-{} backbone weights)", lpips_net_name(net));
    return explicit_path;
  }
  if (auto p = env_path(lpips_backbone_env_var(net))) {
    if (!fs::is_regular_file(*p))
      fail_file(*p, "no such file (named by ${}, the LPIPS-{} backbone weights)", lpips_backbone_env_var(net),
                lpips_net_name(net));
    return p;
  }
  return std::nullopt;
}

std::string lpips_missing_backbone_message(LpipsNet net) {
  return fmt::format(
      "LPIPS-{0} needs the ImageNet weights of torchvision's {1} ({2}, from {3}), which are not "
      "redistributed with instainpaint: download it and pass --lpips-{0} FILE or set {4}=FILE",
      lpips_net_name(net), net == LpipsNet::vgg ? "VGG16" : "AlexNet", lpips_backbone_file_name(net),
      torchvision_url(net), lpips_backbone_env_var(net));
}

std::optional<fs::path> default_lpips_heads_path(LpipsNet net) {
  const std::string file = std::string(lpips_net_name(net)) + ".safetensors";
  if (auto dir = env_path("INSTAINPAINT_LPIPS_HEADS")) {
    if (fs::is_regular_file(*dir / file)) return *dir / file;
    return std::nullopt;
  }
  // ../shared beside the repository, found from the working folder or the executable's.
  std::vector<fs::path> starts = {fs::current_path()};
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) starts.push_back(exe.parent_path());
  for (fs::path dir : starts) {
    for (int up = 0; up < 5 && !dir.empty(); ++up, dir = dir.parent_path()) {
      const fs::path candidate = dir / "shared" / "data" / "lpips" / file;
      if (fs::is_regular_file(candidate)) return candidate;
      if (dir == dir.parent_path()) break;
    }
  }
  return std::nullopt;
}

std::vector<torch::Tensor> read_lpips_heads(const fs::path& path, LpipsNet net) {
  const WeightMap weights = read_weight_file(path);
  std::vector<torch::Tensor> heads;
  const std::vector<int64_t> channels = lpips_stage_channels(net);
  for (size_t k = 0; k < channels.size(); ++k)
    heads.push_back(take_weight(weights, fmt::format("lin{}.model.1.weight", k), {1, channels[k], 1, 1}, path,
                                fmt::format("expected the LPIPS v0.1 {} heads", lpips_net_name(net))));
  return heads;
}

Lpips::Lpips(LpipsNet net, const fs::path& backbone_file, const fs::path& heads_file)
    : Lpips(net, read_weight_file(backbone_file), read_lpips_heads(heads_file, net), backbone_file.string()) {}

Lpips::Lpips(LpipsNet net, const WeightMap& weights, std::vector<torch::Tensor> heads, const std::string& source)
    : net_(net), heads_(std::move(heads)) {
  const fs::path backbone_file(source);
  const std::vector<int64_t> channels = lpips_stage_channels(net);
  if (heads_.size() != channels.size())
    fail("lpips-{}: {} heads given, expected {}", lpips_net_name(net), heads_.size(), channels.size());
  for (size_t k = 0; k < channels.size(); ++k)
    if (heads_[k].sizes() != c10::IntArrayRef({1, channels[k], 1, 1}))
      fail("lpips-{}: head {} has shape [{}], expected [1, {}, 1, 1]", lpips_net_name(net), k,
           fmt::join(heads_[k].sizes(), ", "), channels[k]);
  const std::string hint = fmt::format("expected torchvision's {} state dict, {}",
                                       net == LpipsNet::vgg ? "VGG16" : "AlexNet", lpips_backbone_file_name(net));
  for (const StageSpec& s : spec_of(net)) {
    Stage stage;
    stage.pool_kernel = s.pool_kernel;
    stage.pool_stride = s.pool_stride;
    for (const ConvSpec& c : s.convs) {
      Conv conv;
      const std::string prefix = fmt::format("features.{}.", c.index);
      conv.weight = take_weight(weights, prefix + "weight", {c.out, c.in, c.kernel, c.kernel}, backbone_file, hint);
      conv.bias = take_weight(weights, prefix + "bias", {c.out}, backbone_file, hint);
      conv.stride = c.stride;
      conv.padding = c.padding;
      stage.convs.push_back(conv);
    }
    stages_.push_back(std::move(stage));
  }
}

Lpips Lpips::load(LpipsNet net, const std::optional<fs::path>& backbone_file,
                  const std::optional<fs::path>& heads_file) {
  const std::optional<fs::path> backbone = lpips_backbone_path(net, backbone_file);
  if (!backbone) fail("{}", lpips_missing_backbone_message(net));
  std::optional<fs::path> heads = heads_file;
  if (!heads) heads = default_lpips_heads_path(net);
  if (!heads)
    fail(
        "LPIPS-{0}: the linear heads {0}.safetensors were not found in shared/data/lpips above the working or the "
        "executable's folder: pass --lpips-heads DIR or set INSTAINPAINT_LPIPS_HEADS=DIR",
        lpips_net_name(net));
  return Lpips(net, *backbone, *heads);
}

void Lpips::to(const torch::Device& device) {
  for (Stage& s : stages_)
    for (Conv& c : s.convs) {
      c.weight = c.weight.to(device);
      c.bias = c.bias.to(device);
    }
  for (torch::Tensor& h : heads_) h = h.to(device);
}

std::vector<torch::Tensor> Lpips::features(const torch::Tensor& x_in) const {
  torch::Tensor x = as_image_batch(x_in, "input");
  const torch::Tensor& w0 = stages_.front().convs.front().weight;
  if (x.device() != w0.device())
    fail("lpips: input on {} but the weights are on {}", x.device().str(), w0.device().str());
  x = x.to(w0.scalar_type());
  // Upstream's scaling layer: ImageNet statistics expressed for [-1, 1] inputs.
  const torch::Tensor shift = torch::tensor({-0.030f, -0.088f, -0.188f}, x.options()).view({1, 3, 1, 1});
  const torch::Tensor scale = torch::tensor({0.458f, 0.448f, 0.450f}, x.options()).view({1, 3, 1, 1});
  x = (x - shift) / scale;
  std::vector<torch::Tensor> out;
  for (const Stage& s : stages_) {
    if (s.pool_kernel > 0) x = F::max_pool2d(x, F::MaxPool2dFuncOptions(s.pool_kernel).stride(s.pool_stride));
    for (const Conv& c : s.convs)
      x = torch::relu(F::conv2d(x, c.weight, F::Conv2dFuncOptions().bias(c.bias).stride(c.stride).padding(c.padding)));
    out.push_back(normalize_channels(x));
  }
  return out;
}

std::vector<torch::Tensor> Lpips::stage_distances(const torch::Tensor& a_in, const torch::Tensor& b_in) const {
  const torch::Tensor a = as_image_batch(a_in, "first image"), b = as_image_batch(b_in, "second image");
  if (a.sizes() != b.sizes())
    fail("lpips: the images differ in shape: [{}] vs [{}]", fmt::join(a.sizes(), ", "), fmt::join(b.sizes(), ", "));
  const int64_t min_side = net_ == LpipsNet::vgg ? 16 : 31;  // the smallest input every stage accepts
  if (std::min(a.size(2), a.size(3)) < min_side)
    fail("lpips-{}: images of {}x{} pixels are too small (at least {} pixels per side)", lpips_net_name(net_),
         a.size(3), a.size(2), min_side);
  const int64_t n = a.size(0);
  // One backbone pass over both images.
  const std::vector<torch::Tensor> f = features(torch::cat({a, b.to(a.scalar_type())}, 0));
  std::vector<torch::Tensor> out;
  for (size_t k = 0; k < f.size(); ++k) {
    const torch::Tensor diff = (f[k].narrow(0, 0, n) - f[k].narrow(0, n, n)).pow(2);
    out.push_back(F::conv2d(diff, heads_[k]));
  }
  return out;
}

torch::Tensor Lpips::forward(const torch::Tensor& a, const torch::Tensor& b) const {
  torch::Tensor total;
  for (const torch::Tensor& d : stage_distances(a, b)) {
    const torch::Tensor mean = d.mean({1, 2, 3});
    total = total.defined() ? total + mean : mean;
  }
  return total;
}

torch::Tensor Lpips::spatial_map(const torch::Tensor& a, const torch::Tensor& b) const {
  const torch::Tensor x = as_image_batch(a, "first image");
  const std::vector<int64_t> size = {x.size(2), x.size(3)};
  torch::Tensor total;
  for (const torch::Tensor& d : stage_distances(a, b)) {
    const torch::Tensor up =
        F::interpolate(d, F::InterpolateFuncOptions().size(size).mode(torch::kBilinear).align_corners(false));
    total = total.defined() ? total + up : up;
  }
  return total;
}

torch::Tensor Lpips::masked(const torch::Tensor& a, const torch::Tensor& b, const torch::Tensor& mask) const {
  const torch::Tensor x = as_image_batch(a, "first image");
  torch::Tensor m = mask;
  if (m.dim() == 2) m = m.unsqueeze(0);
  if (m.dim() == 3) m = m.unsqueeze(0);
  if (m.dim() != 4 || m.size(1) != 1 || m.size(2) != x.size(2) || m.size(3) != x.size(3) ||
      (m.size(0) != 1 && m.size(0) != x.size(0)))
    fail("masked lpips: mask of shape [{}] does not fit images of shape [{}]", fmt::join(mask.sizes(), ", "),
         fmt::join(x.sizes(), ", "));
  m = (m > 0.5).to(x.options());
  // The official helper multiplies the [0, 1] images by the mask.
  auto masked_image = [&](const torch::Tensor& t) { return ((as_image_batch(t, "image") + 1) * 0.5 * m) * 2 - 1; };
  const torch::Tensor map = spatial_map(masked_image(a), masked_image(b));
  const torch::Tensor weights = m.expand_as(map);
  return (map * weights).flatten(1).sum(1) / weights.flatten(1).sum(1);
}

}  // namespace ii
