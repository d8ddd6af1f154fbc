#include "segment/segmenter.h"

#include <cmath>
#include <cstdlib>
#include <sstream>

#include "common/cpu_features.h"
#include "common/error.h"
#include "common/parallel.h"
#include "models/cache.h"
#include "segment/pillow_resize.h"
#include "segment/sam_model.h"

namespace ii {
namespace {

using sam::Model;

// SAM's ResizeLongestSide.get_preprocess_shape.
std::pair<int, int> resized_size(int height, int width, int longest) {
  const double scale = longest * 1.0 / std::max(height, width);
  return {static_cast<int>(height * scale + 0.5), static_cast<int>(width * scale + 0.5)};
}

Bytes8Image photo_bytes(const Image& rgb) {
  if (rgb.channels != 3 || rgb.empty()) fail("the segmenter needs an RGB photo, got {} channel(s)", rgb.channels);
  Bytes8Image b{rgb.width, rgb.height, 3, std::vector<uint8_t>(rgb.pixels.size())};
  for (size_t i = 0; i < rgb.pixels.size(); ++i)
    b.pixels[i] = static_cast<uint8_t>(std::lround(std::clamp(rgb.pixels[i], 0.f, 1.f) * 255.f));
  return b;
}

// PositionEmbeddingRandom._pe_encoding: coordinates in [0, 1] -> sin and cos of random frequencies.
torch::Tensor position_encoding(const sam::PromptEncoder& p, const torch::Tensor& coords) {
  torch::Tensor c = 2 * coords - 1;
  c = torch::matmul(c, p.gaussian);
  c = 2 * M_PI * c;
  return torch::cat({torch::sin(c), torch::cos(c)}, -1);
}

// The encoding at the centre of every cell of the embedding's grid: (1, D, G, G).
torch::Tensor dense_position_encoding(const Model& m) {
  const int64_t g = m.embedding_size;
  const torch::Tensor centres = (torch::arange(g, torch::kFloat) + 0.5f) / static_cast<float>(g);
  const torch::Tensor y = centres.view({g, 1}).expand({g, g}), x = centres.view({1, g}).expand({g, g});
  return position_encoding(m.prompt, torch::stack({x, y}, -1)).permute({2, 0, 1}).unsqueeze(0);
}

// Points (1, N, 2) in the encoder's input pixels -> (1, N, D); label 1 object, 0 not, -1 padding.
torch::Tensor embed_points(const sam::PromptEncoder& p, const Model& m, torch::Tensor points, const torch::Tensor& labels) {
  points = points + 0.5f;
  const float side = static_cast<float>(m.image_size);
  torch::Tensor e = position_encoding(p, points / side);
  const torch::Tensor pad = (labels == -1).unsqueeze(-1), off = (labels == 0).unsqueeze(-1), on = (labels == 1).unsqueeze(-1);
  e = torch::where(pad, torch::zeros_like(e), e);
  e = e + pad * p.not_a_point + off * p.point_embeddings[0] + on * p.point_embeddings[1];
  return e;
}

torch::Tensor embed_box(const sam::PromptEncoder& p, const Model& m, const torch::Tensor& box) {
  const torch::Tensor corners = (box + 0.5f).reshape({-1, 2, 2});
  torch::Tensor e = position_encoding(p, corners / static_cast<float>(m.image_size));
  return torch::cat({e.slice(1, 0, 1) + p.point_embeddings[2], e.slice(1, 1, 2) + p.point_embeddings[3]}, 1);
}

torch::Tensor embed_mask(const sam::PromptEncoder& p, const torch::Tensor& mask) {
  torch::Tensor x = torch::gelu(p.mask_norm1.channels(p.mask_conv1(mask)));
  x = torch::gelu(p.mask_norm2.channels(p.mask_conv2(x)));
  return p.mask_conv3(x);
}

// The decoder's 2 x 2 transposed convolutions of stride 2: each output pixel takes one input
// pixel, so it is one matrix product and a pixel shuffle (LibTorch's transposed convolution took
// 21 of a click's 65 ms on 2 cores; its products here in bf16 when the model runs so).
torch::Tensor transposed(const sam::Conv& c, const torch::Tensor& x, bool bf16) {
  const int64_t b = x.size(0), in = x.size(1), h = x.size(2), w = x.size(3), out = c.weight.size(1);
  const torch::Tensor pixels = x.permute({0, 2, 3, 1}).reshape({b * h * w, in});
  const torch::Tensor weight = c.weight.reshape({in, out * 4});
  const torch::Tensor y = bf16 ? torch::mm(pixels.to(torch::kBFloat16), weight.to(torch::kBFloat16)).to(torch::kFloat)
                               : torch::mm(pixels, weight);
  return y.view({b, h, w, out, 2, 2}).permute({0, 3, 1, 4, 2, 5}).reshape({b, out, 2 * h, 2 * w}) +
         c.bias.view({1, out, 1, 1});
}

torch::Tensor run_mlp(const std::vector<sam::Linear>& layers, torch::Tensor x) {
  for (size_t i = 0; i < layers.size(); ++i) {
    x = layers[i](x);
    if (i + 1 < layers.size()) x = torch::relu(x);
  }
  return x;
}

// TwoWayTransformer: tokens (1, T, D) and the image (1, D, G, G) attend to each other.
std::pair<torch::Tensor, torch::Tensor> two_way(const sam::MaskDecoder& d, const torch::Tensor& image,
                                                const torch::Tensor& image_pe, const torch::Tensor& tokens) {
  const torch::Tensor key_pe = image_pe.flatten(2).permute({0, 2, 1});
  torch::Tensor keys = image.flatten(2).permute({0, 2, 1});
  torch::Tensor queries = tokens;
  for (size_t i = 0; i < d.blocks.size(); ++i) {
    const sam::TwoWayBlock& b = d.blocks[i];
    if (i == 0) {
      queries = b.self_attn(queries, queries, queries);  // the first block has no residual here
    } else {
      const torch::Tensor q = queries + tokens;
      queries = queries + b.self_attn(q, q, queries);
    }
    queries = b.norm1(queries);
    queries = b.norm2(queries + b.token_to_image(queries + tokens, keys + key_pe, keys));
    queries = b.norm3(queries + b.lin2(torch::relu(b.lin1(queries))));
    keys = b.norm4(keys + b.image_to_token(keys + key_pe, queries + tokens, queries));
  }
  queries = d.final_norm(queries + d.final_attn(queries + tokens, keys + key_pe, keys));
  return {queries, keys};
}

}  // namespace

torch::Tensor sam::Attention::operator()(const torch::Tensor& q_in, const torch::Tensor& k_in, const torch::Tensor& v_in) const {
  auto heads_of = [&](const torch::Tensor& x) {
    return x.reshape({x.size(0), x.size(1), heads, x.size(2) / heads}).transpose(1, 2);
  };
  const torch::Tensor qh = heads_of(q(q_in)), kh = heads_of(k(k_in)), vh = heads_of(v(v_in));
  torch::Tensor attn = products.matmul(qh, kh.permute({0, 1, 3, 2})) / std::sqrt(static_cast<double>(qh.size(3)));
  torch::Tensor out = products.matmul(torch::softmax(attn, -1), vh).transpose(1, 2);
  return this->out(out.reshape({out.size(0), out.size(1), -1}));
}

Segmenter Segmenter::load(const std::filesystem::path& path, SegmenterPrecision precision) {
  Segmenter s;
  s.model_ = std::make_unique<sam::Model>(sam::read_model(path));
  s.model_->dense_pe = dense_position_encoding(*s.model_);
  const bool bf16 = precision == SegmenterPrecision::BFloat16 ||
                    (precision == SegmenterPrecision::Auto && cpu_features().native_bf16());
  if (bf16) sam::use_bf16(*s.model_);
  s.file_ = path;
  return s;
}

Segmenter::~Segmenter() = default;
Segmenter::Segmenter(Segmenter&&) noexcept = default;
Segmenter& Segmenter::operator=(Segmenter&&) noexcept = default;

const std::string& Segmenter::description() const { return model_->description; }
bool Segmenter::bf16() const { return model_->bf16; }
int Segmenter::image_size() const { return static_cast<int>(model_->image_size); }

torch::Tensor Segmenter::encoder_input(const Image& rgb, int& input_width, int& input_height) const {
  const Model& m = *model_;
  const auto [h, w] = resized_size(rgb.height, rgb.width, static_cast<int>(m.image_size));
  const Bytes8Image resized = resize_like_pillow(photo_bytes(rgb), w, h);
  input_width = w;
  input_height = h;
  torch::Tensor x = torch::from_blob(const_cast<uint8_t*>(resized.pixels.data()), {h, w, 3}, torch::kUInt8)
                        .permute({2, 0, 1})
                        .to(torch::kFloat)
                        .unsqueeze(0);
  const torch::Tensor mean = torch::tensor({123.675f, 116.28f, 103.53f}).view({1, 3, 1, 1});
  const torch::Tensor std = torch::tensor({58.395f, 57.12f, 57.375f}).view({1, 3, 1, 1});
  x = (x - mean) / std;
  return torch::constant_pad_nd(x, {0, m.image_size - w, 0, m.image_size - h});
}

SegmenterImage Segmenter::encode(const Image& rgb) const {
  torch::NoGradGuard no_grad;
  const OneBlasThread blas;
  SegmenterImage out;
  const torch::Tensor input = encoder_input(rgb, out.input_width, out.input_height);
  out.width = rgb.width;
  out.height = rgb.height;
  out.embedding = model_->tiny_vit ? sam::encode_tiny_vit(model_->tiny, input, model_->image_size)
                                   : sam::encode_vit(model_->vit, input);
  return out;
}

namespace {

// The prompt encoder: the points' and the box's embeddings (1, T, D) and the dense one (1, D, G, G),
// from the previous mask or the "no mask" embedding.
std::pair<torch::Tensor, torch::Tensor> prompt_embeddings(const Model& m, const SegmenterImage& image,
                                                          const SegmentPrompt& prompt) {
  // The photo's pixels to the encoder's input (ResizeLongestSide.apply_coords, in double).
  const double sx = static_cast<double>(image.input_width) / image.width;
  const double sy = static_cast<double>(image.input_height) / image.height;
  std::vector<torch::Tensor> sparse;
  if (!prompt.points.empty()) {
    std::vector<float> xy;
    std::vector<int64_t> labels;
    for (const SegmentPoint& p : prompt.points) {
      xy.push_back(static_cast<float>(p.x * sx));
      xy.push_back(static_cast<float>(p.y * sy));
      labels.push_back(p.on_object ? 1 : 0);
    }
    if (!prompt.box) {  // SAM pads points given without a box with one "not a point"
      xy.insert(xy.end(), {-0.5f, -0.5f});  // (0, 0) after the half-pixel shift
      labels.push_back(-1);
    }
    const int64_t n = static_cast<int64_t>(labels.size());
    sparse.push_back(embed_points(m.prompt, m, torch::tensor(xy).view({1, n, 2}), torch::tensor(labels).view({1, n})));
  }
  if (prompt.box) {
    const auto& b = *prompt.box;
    const torch::Tensor box = torch::tensor({static_cast<float>(b[0] * sx), static_cast<float>(b[1] * sy),
                                             static_cast<float>(b[2] * sx), static_cast<float>(b[3] * sy)})
                                  .view({1, 4});
    sparse.push_back(embed_box(m.prompt, m, box));
  }
  const torch::Tensor sparse_embedding = sparse.empty() ? torch::empty({1, 0, m.width}) : torch::cat(sparse, 1);
  const int64_t g = m.embedding_size;
  if (!prompt.previous) return {sparse_embedding, m.prompt.no_mask.view({1, -1, 1, 1}).expand({1, m.width, g, g})};
  const torch::Tensor prev = prompt.previous->to(torch::kFloat).reshape({1, 1, -1, prompt.previous->size(-1)});
  if (prev.size(2) != 4 * g || prev.size(3) != 4 * g)
    fail("a previous mask must be the decoder's {} x {} logits, got {} x {}", 4 * g, 4 * g, prev.size(2), prev.size(3));
  return {sparse_embedding, embed_mask(m.prompt, prev)};
}

// MaskDecoder.predict_masks: every mask token's low-resolution logits (1, M, S/4, S/4) and IoU
// estimates (1, M).
std::pair<torch::Tensor, torch::Tensor> decode_masks(const Model& m, const torch::Tensor& embedding,
                                                     const torch::Tensor& sparse, const torch::Tensor& dense) {
  const sam::MaskDecoder& d = m.decoder;
  const int64_t g = m.embedding_size, masks = d.mask_tokens.size(0);
  const torch::Tensor tokens = torch::cat({torch::cat({d.iou_token, d.mask_tokens}, 0).unsqueeze(0), sparse}, 1);
  const auto [hs, keys] = two_way(d, embedding + dense, m.dense_pe, tokens);
  const torch::Tensor grid = keys.transpose(1, 2).reshape({1, m.width, g, g});
  torch::Tensor up = torch::gelu(d.upscale_norm.channels(transposed(d.upscale1, grid, m.bf16)));
  up = torch::gelu(transposed(d.upscale2, up, m.bf16));
  std::vector<torch::Tensor> hyper;
  for (int64_t i = 0; i < masks; ++i) hyper.push_back(run_mlp(d.hypernetworks[i], hs.select(1, 1 + i)));
  const int64_t side = up.size(2);
  const torch::Tensor low =
      torch::matmul(torch::stack(hyper, 1), up.view({1, up.size(1), side * side})).view({1, masks, side, side});
  return {low, run_mlp(d.iou_head, hs.select(1, 0))};
}

}  // namespace

Segmentation Segmenter::segment(const SegmenterImage& image, const SegmentPrompt& prompt, bool best_only) const {
  torch::NoGradGuard no_grad;
  const OneBlasThread blas;
  const Model& m = *model_;
  if (prompt.points.empty() && !prompt.box && !prompt.previous)
    fail("a segmentation prompt needs a point, a box or a previous mask");
  const auto [sparse, dense] = prompt_embeddings(m, image, prompt);
  auto [low, iou] = decode_masks(m, image.embedding, sparse, dense);
  // The three masks of different extent, or the one mask.
  low = prompt.multimask ? low.slice(1, 1) : low.slice(1, 0, 1);
  iou = prompt.multimask ? iou.slice(1, 1) : iou.slice(1, 0, 1);
  int first = 0;
  torch::Tensor chosen = low;
  if (best_only && low.size(1) > 1) {
    first = static_cast<int>(iou[0].argmax().item<int64_t>());
    chosen = low.slice(1, first, first + 1);
  }
  // Sam.postprocess_masks: to the encoder's size, the padding cut, then to the photo's size.
  torch::Tensor full = torch::upsample_bilinear2d(chosen, {m.image_size, m.image_size}, false);
  full = full.slice(2, 0, image.input_height).slice(3, 0, image.input_width);
  full = torch::upsample_bilinear2d(full, {image.height, image.width}, false);
  return Segmentation{full[0].contiguous(), iou[0].contiguous(), low[0].contiguous(), first};
}

int Segmentation::best() const { return static_cast<int>(scores.argmax().item<int64_t>()); }

Image Segmentation::mask(int k) const {
  if (k < first || k - first >= logits.size(0)) fail("segmentation: mask {} was not brought to the photo's size", k);
  const torch::Tensor m = (logits[k - first] > 0).to(torch::kFloat).contiguous();
  Image out(static_cast<int>(m.size(1)), static_cast<int>(m.size(0)), 1);
  std::copy(m.data_ptr<float>(), m.data_ptr<float>() + out.pixels.size(), out.pixels.begin());
  return out;
}

ClickedMask mask_from_clicks(const Segmenter& segmenter, const Image& photo, const std::vector<Click>& clicks,
                             const std::vector<Click>& not_clicks, StageTimes* stages) {
  if (clicks.empty()) fail("the segmenter needs a click on the object");
  return mask_from_prompt(segmenter, photo, clicks, not_clicks, std::nullopt, stages);
}

ClickedMask mask_from_prompt(const Segmenter& segmenter, const Image& photo, const std::vector<Click>& clicks,
                             const std::vector<Click>& not_clicks, const std::optional<ViewBox>& box,
                             StageTimes* stages) {
  StageTimes unrecorded;
  StageTimes& times = stages ? *stages : unrecorded;
  if (clicks.empty() && !box) fail("the segmenter needs a click on the object or a box around it");
  const SegmenterImage encoded = times.time("segmenter: encode the view", [&] { return segmenter.encode(photo); });
  return mask_from_prompt(segmenter, encoded, clicks, not_clicks, box, stages);
}

ClickedMask mask_from_clicks(const Segmenter& segmenter, const SegmenterImage& encoded, const std::vector<Click>& clicks,
                             const std::vector<Click>& not_clicks, StageTimes* stages) {
  if (clicks.empty()) fail("the segmenter needs a click on the object");
  return mask_from_prompt(segmenter, encoded, clicks, not_clicks, std::nullopt, stages);
}

ClickedMask mask_from_prompt(const Segmenter& segmenter, const SegmenterImage& encoded, const std::vector<Click>& clicks,
                             const std::vector<Click>& not_clicks, const std::optional<ViewBox>& box,
                             StageTimes* stages) {
  StageTimes unrecorded;
  StageTimes& times = stages ? *stages : unrecorded;
  if (clicks.empty() && !box) fail("the segmenter needs a click on the object or a box around it");
  SegmentPrompt prompt;
  prompt.box = box;
  // A click's pixel centres are at +0.5; the network's points are pixel indices (it adds the 0.5).
  for (const Click& c : clicks) prompt.points.push_back({c.x - 0.5, c.y - 0.5, true});
  for (const Click& c : not_clicks) prompt.points.push_back({c.x - 0.5, c.y - 0.5, false});
  prompt.multimask = clicks.size() == 1 && not_clicks.empty() && !box;  // one point is ambiguous: three masks
  const Segmentation s =
      times.time("segmenter: decode the clicks", [&] { return segmenter.segment(encoded, prompt, /*best_only=*/true); });
  ClickedMask out;
  out.chosen = s.best();
  out.mask = s.mask(out.chosen);
  for (int k = 0; k < static_cast<int>(s.scores.size(0)); ++k) out.scores.push_back(s.scores[k].item<double>());
  out.pixels = std::count(out.mask.pixels.begin(), out.mask.pixels.end(), 1.f);
  if (out.pixels == 0) {
    if (clicks.empty()) fail("the segmenter found no object in the box {:.0f},{:.0f},{:.0f},{:.0f}", (*box)[0], (*box)[1], (*box)[2], (*box)[3]);
    fail("the segmenter found no object under the click{} at {:.0f},{:.0f}", clicks.size() == 1 ? "" : "s", clicks[0].x,
         clicks[0].y);
  }
  return out;
}

const nlohmann::json& Segmenter::file_description() const {
  std::call_once(file_description_->once, [&] { file_description_->json = model_file_description(file_); });
  return file_description_->json;
}

nlohmann::json ClickedMask::describe(const Segmenter& segmenter) const {
  nlohmann::json d = segmenter.file_description();  // file, sha256, "from": the cache or a path
  d.update({{"network", segmenter.description()}, {"precision", segmenter.bf16() ? "bf16" : "fp32"},
            {"chosen", chosen}, {"scores", scores}, {"pixels", pixels}});
  return d;
}

SegmenterPrecision parse_segmenter_precision(const std::string& name) {
  if (name == "auto") return SegmenterPrecision::Auto;
  if (name == "fp32") return SegmenterPrecision::Float32;
  if (name == "bf16") return SegmenterPrecision::BFloat16;
  fail("precision: '{}' is not one of auto, fp32, bf16", name);
}

std::optional<std::filesystem::path> segmenter_path(const std::string& flag_value) {
  std::string value = flag_value;
  if (const char* env = std::getenv("INSTAINPAINT_SEGMENTER"); value.empty() && env) value = env;
  if (value == "none") return std::nullopt;
  return choose_model(ModelRole::Segmenter, value.empty() ? "auto" : value).file;
}

}  // namespace ii
