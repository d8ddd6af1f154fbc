#include "eval/inception.h"

#include <torch/nn/functional.h>
#include <cstdlib>

#include <fmt/ranges.h>

#include "common/error.h"
#include "eval/weights.h"

namespace ii {

namespace fs = std::filesystem;
namespace F = torch::nn::functional;

namespace {

constexpr double kBatchNormEps = 1e-3;
constexpr const char* kWeightsFile = "pt_inception-2015-12-05-6726825d.pth";

void add(std::vector<InceptionConvSpec>& s, const std::string& name, int64_t in, int64_t out, int64_t kh, int64_t kw,
         int64_t stride = 1, int64_t ph = 0, int64_t pw = 0) {
  s.push_back({name, in, out, kh, kw, stride, ph, pw});
}

void add_block_a(std::vector<InceptionConvSpec>& s, const std::string& n, int64_t in, int64_t pool_features) {
  add(s, n + ".branch1x1", in, 64, 1, 1);
  add(s, n + ".branch5x5_1", in, 48, 1, 1);
  add(s, n + ".branch5x5_2", 48, 64, 5, 5, 1, 2, 2);
  add(s, n + ".branch3x3dbl_1", in, 64, 1, 1);
  add(s, n + ".branch3x3dbl_2", 64, 96, 3, 3, 1, 1, 1);
  add(s, n + ".branch3x3dbl_3", 96, 96, 3, 3, 1, 1, 1);
  add(s, n + ".branch_pool", in, pool_features, 1, 1);
}

void add_block_b(std::vector<InceptionConvSpec>& s, const std::string& n, int64_t in) {
  add(s, n + ".branch3x3", in, 384, 3, 3, 2);
  add(s, n + ".branch3x3dbl_1", in, 64, 1, 1);
  add(s, n + ".branch3x3dbl_2", 64, 96, 3, 3, 1, 1, 1);
  add(s, n + ".branch3x3dbl_3", 96, 96, 3, 3, 2);
}

void add_block_c(std::vector<InceptionConvSpec>& s, const std::string& n, int64_t in, int64_t c7) {
  add(s, n + ".branch1x1", in, 192, 1, 1);
  add(s, n + ".branch7x7_1", in, c7, 1, 1);
  add(s, n + ".branch7x7_2", c7, c7, 1, 7, 1, 0, 3);
  add(s, n + ".branch7x7_3", c7, 192, 7, 1, 1, 3, 0);
  add(s, n + ".branch7x7dbl_1", in, c7, 1, 1);
  add(s, n + ".branch7x7dbl_2", c7, c7, 7, 1, 1, 3, 0);
  add(s, n + ".branch7x7dbl_3", c7, c7, 1, 7, 1, 0, 3);
  add(s, n + ".branch7x7dbl_4", c7, c7, 7, 1, 1, 3, 0);
  add(s, n + ".branch7x7dbl_5", c7, 192, 1, 7, 1, 0, 3);
  add(s, n + ".branch_pool", in, 192, 1, 1);
}

void add_block_d(std::vector<InceptionConvSpec>& s, const std::string& n, int64_t in) {
  add(s, n + ".branch3x3_1", in, 192, 1, 1);
  add(s, n + ".branch3x3_2", 192, 320, 3, 3, 2);
  add(s, n + ".branch7x7x3_1", in, 192, 1, 1);
  add(s, n + ".branch7x7x3_2", 192, 192, 1, 7, 1, 0, 3);
  add(s, n + ".branch7x7x3_3", 192, 192, 7, 1, 1, 3, 0);
  add(s, n + ".branch7x7x3_4", 192, 192, 3, 3, 2);
}

void add_block_e(std::vector<InceptionConvSpec>& s, const std::string& n, int64_t in) {
  add(s, n + ".branch1x1", in, 320, 1, 1);
  add(s, n + ".branch3x3_1", in, 384, 1, 1);
  add(s, n + ".branch3x3_2a", 384, 384, 1, 3, 1, 0, 1);
  add(s, n + ".branch3x3_2b", 384, 384, 3, 1, 1, 1, 0);
  add(s, n + ".branch3x3dbl_1", in, 448, 1, 1);
  add(s, n + ".branch3x3dbl_2", 448, 384, 3, 3, 1, 1, 1);
  add(s, n + ".branch3x3dbl_3a", 384, 384, 1, 3, 1, 0, 1);
  add(s, n + ".branch3x3dbl_3b", 384, 384, 3, 1, 1, 1, 0);
  add(s, n + ".branch_pool", in, 192, 1, 1);
}

// 3×3 average pool, stride 1, padding 1, padded zeros not counted (TensorFlow's pool).
torch::Tensor avg_pool_same(const torch::Tensor& x) {
  return F::avg_pool2d(x, F::AvgPool2dFuncOptions(3).stride(1).padding(1).count_include_pad(false));
}
torch::Tensor max_pool(const torch::Tensor& x, int64_t stride, int64_t padding = 0) {
  return F::max_pool2d(x, F::MaxPool2dFuncOptions(3).stride(stride).padding(padding));
}

}  // namespace

const char* inception_env_var() { return "INSTAINPAINT_FID_INCEPTION"; }

std::optional<fs::path> inception_weights_path(const std::optional<fs::path>& explicit_path) {
  if (explicit_path) {
    if (!fs::is_regular_file(*explicit_path)) fail_file(*explicit_path, "no such file (Inception weights for FID/KID)");
    return explicit_path;
  }
  if (auto p = env_path(inception_env_var())) {
    if (!fs::is_regular_file(*p))
      fail_file(*p, "no such file (named by ${}, the Inception weights for FID/KID)", inception_env_var());
    return p;
  }
  return std::nullopt;
}

std::string inception_missing_message() {
  return fmt::format(
      "FID/KID need pytorch-fid's Inception-v3 weights ({}, from "
      "https://github.com/mseitzer/pytorch-fid/releases/download/fid_weights/{}), which are not redistributed "
      "with instainpaint: download it and pass --inception FILE or set {}=FILE",
      kWeightsFile, kWeightsFile, inception_env_var());
}

const std::vector<InceptionConvSpec>& inception_conv_specs() {
  static const std::vector<InceptionConvSpec> specs = [] {
    std::vector<InceptionConvSpec> s;
    add(s, "Conv2d_1a_3x3", 3, 32, 3, 3, 2);
    add(s, "Conv2d_2a_3x3", 32, 32, 3, 3);
    add(s, "Conv2d_2b_3x3", 32, 64, 3, 3, 1, 1, 1);
    add(s, "Conv2d_3b_1x1", 64, 80, 1, 1);
    add(s, "Conv2d_4a_3x3", 80, 192, 3, 3);
    add_block_a(s, "Mixed_5b", 192, 32);
    add_block_a(s, "Mixed_5c", 256, 64);
    add_block_a(s, "Mixed_5d", 288, 64);
    add_block_b(s, "Mixed_6a", 288);
    add_block_c(s, "Mixed_6b", 768, 128);
    add_block_c(s, "Mixed_6c", 768, 160);
    add_block_c(s, "Mixed_6d", 768, 160);
    add_block_c(s, "Mixed_6e", 768, 192);
    add_block_d(s, "Mixed_7a", 768);
    add_block_e(s, "Mixed_7b", 1280);
    add_block_e(s, "Mixed_7c", 2048);
    return s;
  }();
  return specs;
}

InceptionFeatures::InceptionFeatures(const WeightMap& weights, const std::string& source) {
  const fs::path file(source);
  const std::string hint = fmt::format("expected pytorch-fid's Inception-v3 state dict, {}", kWeightsFile);
  // torchvision's ImageNet Inception has the same layer names but other weights (1000
  // classes): its features give FIDs that are not comparable with published ones.
  if (auto fc = weights.find("fc.weight"); fc != weights.end() && fc->second.dim() == 2 && fc->second.size(0) != 1008)
    fail_file(file, "fc.weight has {} outputs, not the 1008 of the FID Inception network ({})", fc->second.size(0),
              hint);
  for (const InceptionConvSpec& s : inception_conv_specs()) {
    const torch::Tensor w = take_weight(weights, s.name + ".conv.weight", {s.out, s.in, s.kh, s.kw}, file, hint);
    auto bn = [&](const char* what) {
      return take_weight(weights, s.name + ".bn." + what, {s.out}, file, hint).to(torch::kFloat64);
    };
    const torch::Tensor gamma = bn("weight"), beta = bn("bias"), mean = bn("running_mean"), var = bn("running_var");
    const torch::Tensor factor = gamma / torch::sqrt(var + kBatchNormEps);
    Conv c;
    c.weight = (w.to(torch::kFloat64) * factor.view({-1, 1, 1, 1})).to(torch::kFloat32);
    c.bias = (beta - mean * factor).to(torch::kFloat32);
    c.stride = s.stride;
    c.ph = s.ph;
    c.pw = s.pw;
    convs_[s.name] = c;
  }
}

InceptionFeatures InceptionFeatures::load(const fs::path& file) {
  return InceptionFeatures(read_weight_file(file), file.string());
}

void InceptionFeatures::to(const torch::Device& device) {
  for (auto& [name, c] : convs_) {
    c.weight = c.weight.to(device);
    c.bias = c.bias.to(device);
  }
}

torch::Tensor InceptionFeatures::conv(const std::string& name, const torch::Tensor& x) const {
  const Conv& c = convs_.at(name);
  return torch::relu(
      F::conv2d(x, c.weight, F::Conv2dFuncOptions().bias(c.bias).stride(c.stride).padding({c.ph, c.pw})));
}

torch::Tensor InceptionFeatures::block_a(const std::string& n, const torch::Tensor& x) const {
  const torch::Tensor b1 = conv(n + ".branch1x1", x);
  const torch::Tensor b5 = conv(n + ".branch5x5_2", conv(n + ".branch5x5_1", x));
  const torch::Tensor b3 = conv(n + ".branch3x3dbl_3", conv(n + ".branch3x3dbl_2", conv(n + ".branch3x3dbl_1", x)));
  const torch::Tensor bp = conv(n + ".branch_pool", avg_pool_same(x));
  return torch::cat({b1, b5, b3, bp}, 1);
}

torch::Tensor InceptionFeatures::block_b(const std::string& n, const torch::Tensor& x) const {
  const torch::Tensor b3 = conv(n + ".branch3x3", x);
  const torch::Tensor bd = conv(n + ".branch3x3dbl_3", conv(n + ".branch3x3dbl_2", conv(n + ".branch3x3dbl_1", x)));
  return torch::cat({b3, bd, max_pool(x, 2)}, 1);
}

torch::Tensor InceptionFeatures::block_c(const std::string& n, const torch::Tensor& x) const {
  const torch::Tensor b1 = conv(n + ".branch1x1", x);
  torch::Tensor b7 = x;
  for (const char* k : {".branch7x7_1", ".branch7x7_2", ".branch7x7_3"}) b7 = conv(n + k, b7);
  torch::Tensor bd = x;
  for (const char* k : {".branch7x7dbl_1", ".branch7x7dbl_2", ".branch7x7dbl_3", ".branch7x7dbl_4", ".branch7x7dbl_5"})
    bd = conv(n + k, bd);
  const torch::Tensor bp = conv(n + ".branch_pool", avg_pool_same(x));
  return torch::cat({b1, b7, bd, bp}, 1);
}

torch::Tensor InceptionFeatures::block_d(const std::string& n, const torch::Tensor& x) const {
  const torch::Tensor b3 = conv(n + ".branch3x3_2", conv(n + ".branch3x3_1", x));
  torch::Tensor b7 = x;
  for (const char* k : {".branch7x7x3_1", ".branch7x7x3_2", ".branch7x7x3_3", ".branch7x7x3_4"}) b7 = conv(n + k, b7);
  return torch::cat({b3, b7, max_pool(x, 2)}, 1);
}

torch::Tensor InceptionFeatures::block_e(const std::string& n, const torch::Tensor& x, bool max_pool_branch) const {
  const torch::Tensor b1 = conv(n + ".branch1x1", x);
  const torch::Tensor t3 = conv(n + ".branch3x3_1", x);
  const torch::Tensor b3 = torch::cat({conv(n + ".branch3x3_2a", t3), conv(n + ".branch3x3_2b", t3)}, 1);
  const torch::Tensor td = conv(n + ".branch3x3dbl_2", conv(n + ".branch3x3dbl_1", x));
  const torch::Tensor bd = torch::cat({conv(n + ".branch3x3dbl_3a", td), conv(n + ".branch3x3dbl_3b", td)}, 1);
  // pytorch-fid's port: the last block pools with a max pool (as the TensorFlow graph does).
  const torch::Tensor pooled = max_pool_branch ? max_pool(x, 1, 1) : avg_pool_same(x);
  const torch::Tensor bp = conv(n + ".branch_pool", pooled);
  return torch::cat({b1, b3, bd, bp}, 1);
}

torch::Tensor InceptionFeatures::features_batch(const torch::Tensor& images) const {
  torch::Tensor x = F::interpolate(images, F::InterpolateFuncOptions()
                                               .size(std::vector<int64_t>{input_size, input_size})
                                               .mode(torch::kBilinear)
                                               .align_corners(false));
  x = 2 * x - 1;
  x = conv("Conv2d_2b_3x3", conv("Conv2d_2a_3x3", conv("Conv2d_1a_3x3", x)));
  x = max_pool(x, 2);
  x = conv("Conv2d_4a_3x3", conv("Conv2d_3b_1x1", x));
  x = max_pool(x, 2);
  for (const char* n : {"Mixed_5b", "Mixed_5c", "Mixed_5d"}) x = block_a(n, x);
  x = block_b("Mixed_6a", x);
  for (const char* n : {"Mixed_6b", "Mixed_6c", "Mixed_6d", "Mixed_6e"}) x = block_c(n, x);
  x = block_d("Mixed_7a", x);
  x = block_e("Mixed_7b", x, false);
  x = block_e("Mixed_7c", x, true);
  return x.mean({2, 3});
}

torch::Tensor InceptionFeatures::forward(const torch::Tensor& images, int64_t batch) const {
  if (!images.defined() || images.dim() != 4 || images.size(1) != 3)
    fail("inception: expected (N, 3, H, W) images, got shape [{}]",
         images.defined() ? fmt::format("{}", fmt::join(images.sizes(), ", ")) : std::string("undefined"));
  const torch::Device device = convs_.begin()->second.weight.device();
  torch::NoGradGuard no_grad;
  std::vector<torch::Tensor> out;
  for (int64_t i = 0; i < images.size(0); i += batch) {
    const torch::Tensor chunk = images.narrow(0, i, std::min(batch, images.size(0) - i)).to(device, torch::kFloat32);
    out.push_back(features_batch(chunk).cpu());
  }
  return torch::cat(out, 0);
}

}  // namespace ii
