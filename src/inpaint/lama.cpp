#include "inpaint/lama.h"

#include <optional>

#include <fmt/format.h>

#include "common/error.h"
#include "common/parallel.h"
#include "io/pth.h"
#include "tensor/tensor_taker.h"

namespace ii {

namespace lama {

// Pads the last two dimensions by `p` on each side by reflection (the edge not repeated), as
// torch's reflection_pad2d, for any type (LibTorch 1.13 has it for float only, not bf16: there by
// gathering rows and columns).
// x's rows and columns (the last two dimensions) at out-of-range positions, `source(k, n)` the row
// or column that position k of a side of n takes: a pad of any kind, for any type.
template <typename Source>
torch::Tensor gather_rows_and_columns(const torch::Tensor& x, int64_t from_row, int64_t to_row, int64_t from_column,
                                      int64_t to_column, Source source) {
  auto indices = [&](int64_t from, int64_t to, int64_t n) {
    std::vector<int64_t> idx;
    for (int64_t k = from; k < to; ++k) idx.push_back(source(k, n));
    return torch::tensor(idx, torch::kLong).to(x.device());
  };
  return x.index_select(2, indices(from_row, to_row, x.size(2)))
      .index_select(3, indices(from_column, to_column, x.size(3)));
}

torch::Tensor reflect_pad(const torch::Tensor& x, int64_t p) {
  if (x.scalar_type() == torch::kFloat) return at::reflection_pad2d(x, {p, p, p, p});
  return gather_rows_and_columns(x, -p, x.size(2) + p, -p, x.size(3) + p,
                                 [](int64_t k, int64_t n) { return k < 0 ? -k : k >= n ? 2 * (n - 1) - k : k; });
}

// A convolution; `reflect` pads by reflection before it (FFC's padding_mode), else by zeros.
// Batch norms after it are folded into its weights and bias at load.
struct Conv {
  torch::Tensor weight, bias;  // bias undefined when the layer has none
  int64_t stride = 1, padding = 0;
  bool reflect = true;
  torch::Tensor operator()(const torch::Tensor& x) const {
    if (reflect && padding > 0)
      return torch::conv2d(reflect_pad(x, padding), weight, bias, stride);
    return torch::conv2d(x, weight, bias, stride, padding);
  }
  // y = scale * conv(x) + shift, per output channel; `with_shift` false: the shift goes elsewhere.
  void fold(const torch::Tensor& scale, const torch::Tensor& shift, bool with_shift) {
    weight = weight * scale.view({-1, 1, 1, 1});
    if (bias.defined()) bias = bias * scale;
    if (with_shift) bias = bias.defined() ? bias + shift : shift.clone();
  }
  // Its weight and bias through `f` (to another type, to another device).
  template <typename F>
  void map(F f) {
    weight = f(weight);
    if (bias.defined()) bias = f(bias);
  }
};

// A batch norm in inference as one scale and shift per channel (folded into what precedes it).
struct Norm {
  torch::Tensor scale, shift;  // (C)
};

// SpectralTransform: a 1x1 convolution, the Fourier unit (a 1x1 convolution over the real and
// imaginary parts of the channels' 2D spectra), and a 1x1 convolution of the sum. The transforms
// run in float whatever the convolutions' type (no bf16 FFT).
struct Spectral {
  Conv reduce, spectrum, expand;  // reduce and spectrum: their norms folded in
  torch::Tensor operator()(const torch::Tensor& x) const {
    const torch::Tensor reduced = torch::relu(reduce(x));
    return expand(reduced + fourier(reduced));
  }
  torch::Tensor fourier(const torch::Tensor& x) const {
    const int64_t b = x.size(0), c = x.size(1), h = x.size(2), w = x.size(3);
    // (b, c, h, w/2+1) complex -> (b, c, 2, h, w/2+1) real -> (b, 2c, h, w/2+1): channel k's real
    // part, then its imaginary part.
    const torch::Tensor spectrum_of_x =
        at::fft_rfftn(x.to(torch::kFloat), c10::nullopt, std::vector<int64_t>{-2, -1}, "ortho");
    torch::Tensor s = torch::view_as_real(spectrum_of_x).permute({0, 1, 4, 2, 3}).reshape({b, 2 * c, h, -1});
    s = torch::relu(spectrum(s.to(x.scalar_type())));
    s = s.to(torch::kFloat).view({b, -1, 2, h, s.size(3)}).permute({0, 1, 3, 4, 2}).contiguous();
    return at::fft_irfftn(torch::view_as_complex(s), std::vector<int64_t>{h, w}, std::vector<int64_t>{-2, -1}, "ortho")
        .to(x.scalar_type());
  }
};

// FFC_BN_ACT: local and global channels, four paths between them, a norm (folded into the paths)
// and a ReLU on each side. A missing path (no global channels in or out) is left undefined.
struct Ffc {
  std::optional<Conv> l2l, l2g, g2l;
  std::optional<Spectral> g2g;
  // (local, global) -> (local, global); an undefined tensor is an empty side.
  std::pair<torch::Tensor, torch::Tensor> operator()(const torch::Tensor& l, const torch::Tensor& g) const {
    torch::Tensor out_l, out_g;
    if (l2l) out_l = (*l2l)(l);
    if (g2l && g.defined()) out_l = out_l.defined() ? out_l.add_((*g2l)(g)) : (*g2l)(g);
    if (l2g) out_g = (*l2g)(l);
    if (g2g && g.defined()) out_g = out_g.defined() ? out_g.add_((*g2g)(g)) : (*g2g)(g);
    if (out_l.defined()) out_l.relu_();
    if (out_g.defined()) out_g.relu_();
    return {out_l, out_g};
  }
};

struct Up {
  torch::Tensor weight, bias;  // ConvTranspose2d (in, out, 3, 3), stride 2; its norm folded in
};

struct Generator {
  Ffc init;                                    // after a reflection pad of 3: 7x7
  std::vector<Ffc> down;                       // 3x3, stride 2
  std::vector<std::pair<Ffc, Ffc>> blocks;     // residual
  std::vector<Up> up;
  Conv out;                                    // after a reflection pad of 3: 7x7, to RGB
  int64_t ngf = 0;
  bool bf16 = false;                           // convolutions in bf16 (the transforms in float)
  torch::Device device = torch::kCPU;          // where its weights are and it runs
};

}  // namespace lama

namespace {

using lama::Conv;
using lama::Norm;
using lama::Ffc;

Norm read_norm(TensorTaker& t, const std::string& key, int64_t channels) {
  const torch::Tensor gamma = t.take(key + ".weight", {channels}), beta = t.take(key + ".bias", {channels});
  const torch::Tensor mean = t.take(key + ".running_mean", {channels}), var = t.take(key + ".running_var", {channels});
  const torch::Tensor scale = gamma / torch::sqrt(var + 1e-5);
  return Norm{scale, beta - mean * scale};
}

Conv read_conv(TensorTaker& t, const std::string& key, int64_t out, int64_t in, int64_t k, int64_t stride,
               int64_t padding, bool bias = false) {
  Conv c;
  c.weight = t.take(key + ".weight", {out, in, k, k});
  if (bias) c.bias = t.take(key + ".bias", {out});
  c.stride = stride;
  c.padding = padding;
  return c;
}

// One FFC_BN_ACT under `key` from `in` channels ((in_l, in_g)) to `out` ((out_l, out_g)).
Ffc read_ffc(TensorTaker& t, const std::string& key, std::pair<int64_t, int64_t> in, std::pair<int64_t, int64_t> out,
             int64_t k, int64_t stride, int64_t padding) {
  const auto [in_l, in_g] = in;
  const auto [out_l, out_g] = out;
  const std::string f = key + ".ffc.";
  Ffc ffc;
  if (in_l > 0 && out_l > 0) ffc.l2l = read_conv(t, f + "convl2l", out_l, in_l, k, stride, padding);
  if (in_l > 0 && out_g > 0) ffc.l2g = read_conv(t, f + "convl2g", out_g, in_l, k, stride, padding);
  if (in_g > 0 && out_l > 0) ffc.g2l = read_conv(t, f + "convg2l", out_l, in_g, k, stride, padding);
  if (in_g > 0 && out_g > 0) {
    if (stride != 1) fail("{}: {}: a Fourier unit with stride {} (big-lama's have 1)", t.file().string(), key, stride);
    if (t.has(f + "convg2g.lfu.conv_layer.weight"))
      fail("{}: {}convg2g.lfu: LaMa's local Fourier unit (enable_lfu) is not supported; big-lama has none",
           t.file().string(), f);
    lama::Spectral s;
    const int64_t half = out_g / 2;
    s.reduce = read_conv(t, f + "convg2g.conv1.0", half, in_g, 1, 1, 0);
    const Norm reduce_norm = read_norm(t, f + "convg2g.conv1.1", half);
    s.reduce.fold(reduce_norm.scale, reduce_norm.shift, true);
    s.spectrum = read_conv(t, f + "convg2g.fu.conv_layer", 2 * half, 2 * half, 1, 1, 0);
    const Norm spectrum_norm = read_norm(t, f + "convg2g.fu.bn", 2 * half);
    s.spectrum.fold(spectrum_norm.scale, spectrum_norm.shift, true);
    s.expand = read_conv(t, f + "convg2g.conv2", out_g, half, 1, 1, 0);
    ffc.g2g = s;
  }
  // Each side's norm: its scale into every path that ends there, its shift into the first one.
  if (out_l > 0) {
    const Norm n = read_norm(t, key + ".bn_l", out_l);
    if (ffc.l2l) ffc.l2l->fold(n.scale, n.shift, true);
    if (ffc.g2l) ffc.g2l->fold(n.scale, n.shift, !ffc.l2l);
  }
  if (out_g > 0) {
    const Norm n = read_norm(t, key + ".bn_g", out_g);
    if (ffc.l2g) ffc.l2g->fold(n.scale, n.shift, true);
    if (ffc.g2g) ffc.g2g->expand.fold(n.scale, n.shift, !ffc.l2g);
  }
  return ffc;
}

// The global share of a layer's output channels, from its local-to-global convolution.
int64_t global_out(const TensorTaker& t, const std::string& key) {
  return t.has(key + ".ffc.convl2g.weight") ? t.size(t.shape(key + ".ffc.convl2g.weight"), 0) : 0;
}

lama::Generator read_generator(TensorTaker& t, const std::string& p) {
  lama::Generator g;
  const std::string first = p + "1.ffc.convl2l.weight";
  if (!t.has(first))
    fail("{}: no LaMa generator in it ({} is missing; big-lama/models/best.ckpt has it)", t.file().string(), first);
  g.ngf = t.size(t.shape(first), 0);
  g.init = read_ffc(t, p + "1", {4, 0}, {g.ngf, 0}, 7, 1, 0);
  g.init.l2l->reflect = false;  // padded by the generator's ReflectionPad2d(3) before it
  int64_t i = 2, channels = g.ngf, global = 0;
  for (; t.has(p + std::to_string(i) + ".ffc.convl2l.weight"); ++i) {
    const std::string key = p + std::to_string(i);
    const int64_t out = t.size(t.shape(key + ".ffc.convl2l.weight"), 0) + global_out(t, key);
    const int64_t out_g = global_out(t, key);
    g.down.push_back(read_ffc(t, key, {channels - global, global}, {out - out_g, out_g}, 3, 2, 1));
    channels = out;
    global = out_g;
  }
  if (g.down.empty()) fail("{}: {}2 is missing: a LaMa generator downsamples", t.file().string(), p);
  for (; t.has(p + std::to_string(i) + ".conv1.ffc.convl2l.weight"); ++i) {
    const std::string key = p + std::to_string(i);
    const std::pair<int64_t, int64_t> split{channels - global, global};
    g.blocks.emplace_back(read_ffc(t, key + ".conv1", split, split, 3, 1, 1),
                          read_ffc(t, key + ".conv2", split, split, 3, 1, 1));
  }
  ++i;  // ConcatTupleLayer
  for (size_t k = 0; k < g.down.size(); ++k, i += 3) {
    const std::string key = p + std::to_string(i);
    lama::Up up;
    up.weight = t.take(key + ".weight", {channels, channels / 2, 3, 3});
    up.bias = t.take(key + ".bias", {channels / 2});
    channels /= 2;
    const Norm n = read_norm(t, p + std::to_string(i + 1), channels);
    up.weight = up.weight * n.scale.view({1, -1, 1, 1});  // (in, out, k, k): per output channel
    up.bias = up.bias * n.scale + n.shift;
    g.up.push_back(up);
  }
  ++i;  // ReflectionPad2d(3)
  g.out = read_conv(t, p + std::to_string(i), 3, channels, 7, 1, 0, true);
  g.out.reflect = false;
  return g;
}

// The generator's tensors: a Lightning checkpoint's under "generator.", or a bare generator's.
TensorMap generator_tensors(const std::filesystem::path& file) {
  PickleOptions options;
  options.opaque_objects = true;  // Lightning keeps its callbacks' classes beside the weights
  TensorMap out;
  for (const auto& [key, tensor] : read_pth_tensors(file, options)) {
    std::string k = key;
    if (k.rfind("state_dict.", 0) == 0) k = k.substr(11);
    if (k.rfind("generator.", 0) == 0) out.emplace(k.substr(10), tensor_from_pth(tensor, file));
    else if (k.rfind("model.", 0) == 0) out.emplace(k, tensor_from_pth(tensor, file));
  }
  return out;
}

// np.pad(mode="symmetric") on the bottom and right to (height, width): the edge row repeated,
// then the rows before it.
torch::Tensor pad_symmetric(const torch::Tensor& x, int64_t height, int64_t width) {
  return lama::gather_rows_and_columns(x, 0, height, 0, width, [](int64_t k, int64_t n) {
    const int64_t t = k % (2 * n);
    return t < n ? t : 2 * n - 1 - t;
  });
}

// fn(conv) for every convolution of the generator (not the transposed ones).
template <typename Fn>
void for_each_conv(lama::Generator& g, Fn fn) {
  auto ffc = [&](Ffc& f) {
    for (std::optional<Conv>* c : {&f.l2l, &f.l2g, &f.g2l})
      if (*c) fn(**c);
    if (f.g2g)
      for (Conv* c : {&f.g2g->reduce, &f.g2g->spectrum, &f.g2g->expand}) fn(*c);
  };
  ffc(g.init);
  for (Ffc& d : g.down) ffc(d);
  for (auto& [a, b] : g.blocks) ffc(a), ffc(b);
  fn(g.out);
}

// The convolutions' weights in bf16 (products on oneDNN's bf16 kernels); the transforms and the
// transposed convolutions stay float.
void to_bf16(lama::Generator& g) {
  for_each_conv(g, [](Conv& c) { c.map([](const torch::Tensor& t) { return t.to(torch::kBFloat16); }); });
  g.bf16 = true;
}

// Every weight on `device` (a GPU: LibTorch's CUDA kernels and cuFFT).
void to_device(lama::Generator& g, torch::Device device) {
  for_each_conv(g, [&](Conv& c) { c.map([&](const torch::Tensor& t) { return t.to(device); }); });
  for (lama::Up& u : g.up) u.weight = u.weight.to(device), u.bias = u.bias.to(device);
  g.device = device;
}

}  // namespace

Lama Lama::load(const std::filesystem::path& file, bool bf16, torch::Device device) {
  std::error_code ec;
  if (!std::filesystem::exists(file, ec)) fail("{}: no such LaMa file", file.string());
  TensorTaker t(generator_tensors(file), file, "big-lama's generator", "LaMa generator's layer");
  Lama out;
  lama::Generator g = read_generator(t, "model.");
  if (bf16) to_bf16(g);
  if (!device.is_cpu()) to_device(g, device);
  out.generator_ = std::make_shared<const lama::Generator>(std::move(g));
  t.check_all_used({"num_batches_tracked"});
  out.file_ = file;
  return out;
}

std::string Lama::description() const {
  return fmt::format("LaMa FFC-ResNet (ngf {}, {} blocks)", generator_->ngf, generator_->blocks.size());
}

bool Lama::bf16() const { return generator_->bf16; }

torch::Tensor Lama::generate(const torch::Tensor& input) const {
  torch::NoGradGuard no_grad;
  const OneBlasThread blas;  // LibTorch calls OpenBLAS inside its own threads (common/parallel.h)
  const lama::Generator& g = *generator_;
  auto pad3 = [](const torch::Tensor& x) { return lama::reflect_pad(x, 3); };
  const torch::ScalarType type = g.bf16 ? torch::kBFloat16 : torch::kFloat;
  auto [l, gl] = g.init(pad3(input.to(type)), torch::Tensor());
  for (const Ffc& d : g.down) std::tie(l, gl) = d(l, gl);
  for (const auto& [a, b] : g.blocks) {
    auto [l1, g1] = a(l, gl);
    auto [l2, g2] = b(l1, g1);
    l = l + l2;
    gl = gl + g2;
  }
  torch::Tensor x = torch::cat({l, gl}, 1);
  // The transposed convolutions in float: LibTorch 1.13's bf16 one takes its weight for a plain
  // convolution's.
  for (const lama::Up& u : g.up) x = torch::conv_transpose2d(x.to(torch::kFloat), u.weight, u.bias, 2, 1, 1).relu_();
  x = x.to(type);
  return torch::sigmoid(g.out(pad3(x)).to(torch::kFloat));
}

Image Lama::inpaint(const Image& photo, const Image& mask) const {
  if (photo.channels != 3) fail("LaMa paints an RGB photo, not {} channels", photo.channels);
  if (mask.width != photo.width || mask.height != photo.height)
    fail("LaMa: the mask is {}x{} but the photo {}x{}", mask.width, mask.height, photo.width, photo.height);
  const int64_t H = photo.height, W = photo.width;
  const torch::Device device = generator_->device;
  const torch::Tensor rgb = torch::from_blob(const_cast<float*>(photo.pixels.data()), {1, H, W, 3}, torch::kFloat)
                                .to(device)
                                .permute({0, 3, 1, 2});
  const torch::Tensor region = torch::from_blob(const_cast<float*>(mask.pixels.data()), {1, 1, H, W}, torch::kFloat)
                                   .to(device)
                                   .gt(0.5)
                                   .to(torch::kFloat);
  const int64_t h8 = (H + 7) / 8 * 8, w8 = (W + 7) / 8 * 8;
  const torch::Tensor padded = pad_symmetric(rgb, h8, w8), padded_region = pad_symmetric(region, h8, w8);
  const torch::Tensor painted = generate(torch::cat({padded * (1 - padded_region), padded_region}, 1));
  const torch::Tensor blended = (padded_region * painted + (1 - padded_region) * padded)
                                    .slice(2, 0, H)
                                    .slice(3, 0, W)
                                    .permute({0, 2, 3, 1})
                                    .to(torch::kCPU)
                                    .contiguous();
  Image out(photo.width, photo.height, 3);
  std::copy(blended.data_ptr<float>(), blended.data_ptr<float>() + blended.numel(), out.pixels.begin());
  return out;
}

}  // namespace ii
