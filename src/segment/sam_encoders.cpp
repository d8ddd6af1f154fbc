// SAM's ViT and MobileSAM's TinyViT image encoders, and the modules' basic layers.
#include "common/error.h"
#include "segment/sam_model.h"

namespace ii::sam {

torch::Tensor Linear::operator()(const torch::Tensor& x) const {
  if (half_weight.defined()) return torch::linear(x.to(torch::kBFloat16), half_weight, half_bias).to(torch::kFloat);
  return torch::linear(x, weight, bias);
}

torch::Tensor Norm::operator()(const torch::Tensor& x) const {
  return torch::layer_norm(x, {weight.size(0)}, weight, bias, eps);
}

torch::Tensor Norm::channels(const torch::Tensor& x) const {
  const torch::Tensor u = x.mean(1, true);
  const torch::Tensor s = (x - u).pow(2).mean(1, true);
  return weight.view({-1, 1, 1}) * ((x - u) / torch::sqrt(s + eps)) + bias.view({-1, 1, 1});
}

torch::Tensor Neck::operator()(const torch::Tensor& x) const { return norm2.channels(conv2(norm1.channels(conv1(x)))); }

torch::Tensor Conv::operator()(const torch::Tensor& x) const {
  if (half_weight.defined())
    return torch::conv2d(x.to(torch::kBFloat16), half_weight, half_bias, {stride, stride}, {padding, padding}, {1, 1}, groups)
        .to(torch::kFloat);
  return torch::conv2d(x, weight, bias, {stride, stride}, {padding, padding}, {1, 1}, groups);
}

namespace {
template <class Layer>
void halve(Layer& l) {
  l.half_weight = l.weight.to(torch::kBFloat16);
  if (l.bias.defined()) l.half_bias = l.bias.to(torch::kBFloat16);
}
}  // namespace

torch::Tensor Products::matmul(const torch::Tensor& a, const torch::Tensor& b) const {
  if (!bf16) return torch::matmul(a, b);
  return torch::matmul(a.to(torch::kBFloat16), b.to(torch::kBFloat16)).to(torch::kFloat);
}

void use_bf16(Model& m) {
  m.bf16 = true;
  if (m.tiny_vit) {
    TinyVitEncoder& e = m.tiny;
    for (Conv* c : {&e.embed1, &e.embed2, &e.neck.conv1, &e.neck.conv2}) halve(*c);
    for (TinyVitStage& s : e.stages) {
      for (MbConv& c : s.convs) {
        halve(c.conv1);
        halve(c.conv2);
        halve(c.conv3);
      }
      for (TinyVitBlock& b : s.blocks) {
        for (Linear* l : {&b.qkv, &b.proj, &b.fc1, &b.fc2}) halve(*l);
        halve(b.local_conv);
        b.products.bf16 = true;
      }
      if (s.has_merge)
        for (Conv* c : {&s.merge.conv1, &s.merge.conv2, &s.merge.conv3}) halve(*c);
    }
  } else {
    VitEncoder& e = m.vit;
    for (Conv* c : {&e.patch_embed, &e.neck.conv1, &e.neck.conv2}) halve(*c);
    for (VitBlock& b : e.blocks) {
      for (Linear* l : {&b.qkv, &b.proj, &b.lin1, &b.lin2}) halve(*l);
      b.products.bf16 = true;
    }
  }
  auto attention = [](Attention& a) {
    for (Linear* l : {&a.q, &a.k, &a.v, &a.out}) halve(*l);
    a.products.bf16 = true;
  };
  for (TwoWayBlock& b : m.decoder.blocks) {
    for (Attention* a : {&b.self_attn, &b.token_to_image, &b.image_to_token}) attention(*a);
    halve(b.lin1);
    halve(b.lin2);
  }
  attention(m.decoder.final_attn);
}

namespace {

// ---- SAM's ViT ----

// (B, H, W, C) -> (B * windows, w, w, C), zero-padded to whole windows.
torch::Tensor vit_windows(const torch::Tensor& x, int64_t w) {
  const int64_t b = x.size(0), h = x.size(1), wd = x.size(2), c = x.size(3);
  const int64_t ph = (w - h % w) % w, pw = (w - wd % w) % w;
  torch::Tensor padded = ph > 0 || pw > 0 ? torch::constant_pad_nd(x, {0, 0, 0, pw, 0, ph}) : x;
  const int64_t hp = h + ph, wp = wd + pw;
  return padded.view({b, hp / w, w, wp / w, w, c}).permute({0, 1, 3, 2, 4, 5}).contiguous().view({-1, w, w, c});
}

torch::Tensor vit_unwindows(const torch::Tensor& windows, int64_t w, int64_t h, int64_t wd) {
  const int64_t hp = (h + w - 1) / w * w, wp = (wd + w - 1) / w * w;
  const int64_t b = windows.size(0) / (hp / w * (wp / w));
  torch::Tensor x = windows.view({b, hp / w, wp / w, w, w, -1}).permute({0, 1, 3, 2, 4, 5}).contiguous().view({b, hp, wp, -1});
  return hp > h || wp > wd ? x.slice(1, 0, h).slice(2, 0, wd).contiguous() : x;
}

// The relative-position rows for every (query, key) pair along one axis of `size` tokens.
torch::Tensor relative_rows(const torch::Tensor& table, int64_t size) {
  const torch::Tensor coords = torch::arange(size).unsqueeze(1) - torch::arange(size).unsqueeze(0) + (size - 1);
  return table.index({coords});  // (size, size, head_dim)
}

torch::Tensor vit_attention(const VitBlock& blk, const torch::Tensor& x) {
  const int64_t b = x.size(0), h = x.size(1), w = x.size(2), heads = blk.heads;
  const torch::Tensor qkv = blk.qkv(x).reshape({b, h * w, 3, heads, -1}).permute({2, 0, 3, 1, 4}).reshape({3, b * heads, h * w, -1});
  const torch::Tensor q = qkv[0], k = qkv[1], v = qkv[2];
  const int64_t head_dim = q.size(2);
  const double scale = std::pow(static_cast<double>(head_dim), -0.5);  // as the reference writes it
  const torch::Tensor rh = relative_rows(blk.rel_pos_h, h), rw = relative_rows(blk.rel_pos_w, w);
  // Heads in groups: a global block's scores are (tokens x tokens) per head.
  const int64_t group = std::max<int64_t>(1, (int64_t{1} << 27) / std::max<int64_t>(1, h * w * h * w));
  std::vector<torch::Tensor> outs;
  for (int64_t s = 0; s < b * heads; s += group) {
    const int64_t e = std::min(b * heads, s + group);
    const torch::Tensor qs = q.slice(0, s, e), ks = k.slice(0, s, e), vs = v.slice(0, s, e);
    torch::Tensor attn = blk.products.matmul(qs * scale, ks.transpose(-2, -1));
    const torch::Tensor rq = qs.reshape({e - s, h, w, head_dim});
    // einsum("bhwc,hkc->bhwk") and einsum("bhwc,wkc->bhwk") as batched products.
    const torch::Tensor rel_h = blk.products.matmul(rq, rh.transpose(1, 2).unsqueeze(0));
    const torch::Tensor rel_w = blk.products.matmul(rq.transpose(1, 2), rw.transpose(1, 2).unsqueeze(0)).transpose(1, 2);
    attn = (attn.view({e - s, h, w, h, w}) + rel_h.unsqueeze(4) + rel_w.unsqueeze(3)).view({e - s, h * w, h * w});
    outs.push_back(blk.products.matmul(torch::softmax(attn, -1), vs));
  }
  const torch::Tensor out = outs.size() == 1 ? outs[0] : torch::cat(outs, 0);
  return blk.proj(out.view({b, heads, h, w, -1}).permute({0, 2, 3, 1, 4}).reshape({b, h, w, -1}));
}

torch::Tensor vit_block(const VitBlock& blk, const torch::Tensor& x) {
  torch::Tensor y = blk.norm1(x);
  const int64_t h = x.size(1), w = x.size(2);
  if (blk.window > 0) y = vit_windows(y, blk.window);
  y = vit_attention(blk, y);
  if (blk.window > 0) y = vit_unwindows(y, blk.window, h, w);
  torch::Tensor out = x + y;
  return out + blk.lin2(torch::gelu(blk.lin1(blk.norm2(out))));
}

// ---- MobileSAM's TinyViT ----

torch::Tensor tiny_attention(const TinyVitBlock& blk, const torch::Tensor& x) {
  const int64_t b = x.size(0), n = x.size(1);
  const torch::Tensor qkv = blk.qkv(blk.attn_norm(x)).view({b, n, blk.heads, -1});
  const auto parts = qkv.split_with_sizes({blk.key_dim, blk.key_dim, blk.key_dim}, 3);
  const torch::Tensor q = parts[0].permute({0, 2, 1, 3}), k = parts[1].permute({0, 2, 1, 3}), v = parts[2].permute({0, 2, 1, 3});
  const double scale = std::pow(static_cast<double>(blk.key_dim), -0.5);
  const torch::Tensor attn = torch::softmax(blk.products.matmul(q, k.transpose(-2, -1)) * scale + blk.biases, -1);
  return blk.proj(blk.products.matmul(attn, v).transpose(1, 2).reshape({b, n, -1}));
}

// x: (B, H * W, C) tokens of an H x W grid.
torch::Tensor tiny_block(const TinyVitBlock& blk, const torch::Tensor& x, int64_t h, int64_t w) {
  const int64_t b = x.size(0), l = x.size(1), c = x.size(2), ws = blk.window;
  torch::Tensor y;
  if (h == ws && w == ws) {
    y = tiny_attention(blk, x);
  } else {
    // Windows of the raw tokens: the padding is zeros before the attention's own norm.
    const int64_t ph = (ws - h % ws) % ws, pw = (ws - w % ws) % ws;
    torch::Tensor g = x.view({b, h, w, c});
    if (ph > 0 || pw > 0) g = torch::constant_pad_nd(g, {0, 0, 0, pw, 0, ph});
    const int64_t hp = h + ph, wp = w + pw, nh = hp / ws, nw = wp / ws;
    g = g.view({b, nh, ws, nw, ws, c}).transpose(2, 3).reshape({b * nh * nw, ws * ws, c});
    g = tiny_attention(blk, g);
    g = g.view({b, nh, nw, ws, ws, c}).transpose(2, 3).reshape({b, hp, wp, c});
    if (ph > 0 || pw > 0) g = g.slice(1, 0, h).slice(2, 0, w).contiguous();
    y = g.view({b, l, c});
  }
  torch::Tensor out = x + y;
  out = blk.local_conv(out.transpose(1, 2).reshape({b, c, h, w})).view({b, c, l}).transpose(1, 2);
  return out + blk.fc2(torch::gelu(blk.fc1(blk.mlp_norm(out))));
}

}  // namespace

torch::Tensor encode_vit(const VitEncoder& e, const torch::Tensor& image) {
  torch::Tensor x = e.patch_embed(image).permute({0, 2, 3, 1}) + e.pos_embed;
  for (const VitBlock& blk : e.blocks) x = vit_block(blk, x);
  return e.neck(x.permute({0, 3, 1, 2}));
}

torch::Tensor encode_tiny_vit(const TinyVitEncoder& e, const torch::Tensor& image, int64_t image_size) {
  const int64_t last = image_size / 16;  // the tokens' side at the end
  torch::Tensor x = e.embed2(torch::gelu(e.embed1(image)));  // (B, C, S/4, S/4)
  int64_t h = x.size(2), w = x.size(3);
  bool tokens = false;  // (B, L, C) rather than (B, C, H, W)
  for (const TinyVitStage& stage : e.stages) {
    for (const MbConv& c : stage.convs) {
      torch::Tensor y = torch::gelu(c.conv1(x));
      y = torch::gelu(c.conv2(y));
      x = torch::gelu(c.conv3(y) + x);
    }
    for (const TinyVitBlock& blk : stage.blocks) x = tiny_block(blk, x, h, w);
    if (stage.has_merge) {
      if (tokens) x = x.view({x.size(0), h, w, -1}).permute({0, 3, 1, 2});
      PatchMerging m = stage.merge;
      m.conv2.stride = h > last ? 2 : 1;
      x = m.conv3(torch::gelu(m.conv2(torch::gelu(m.conv1(x)))));
      h = x.size(2);
      w = x.size(3);
      x = x.flatten(2).transpose(1, 2);
      tokens = true;
    }
  }
  if (!tokens) x = x.flatten(2).transpose(1, 2);
  if (h != last || w != last) fail("TinyViT ends at {} x {} tokens, expected {} x {}", h, w, last, last);
  x = x.reshape({x.size(0), last, last, -1}).permute({0, 3, 1, 2});
  return e.neck(x);
}

}  // namespace ii::sam
