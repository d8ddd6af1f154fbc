#include "render/cpu/cpu_rasterizer.h"

#include <ATen/Parallel.h>

#include "common/cpu_features.h"
#include "common/parallel.h"
#include "render/cpu/raster_tiles.h"

#include <algorithm>
#include <atomic>
#include <cstring>
#include <memory>
#include <vector>

namespace ii::render_detail {

using splat::CameraParams;
using splat::kTileSize;
using splat::PixelBox;
using splat::Splat2D;
using splat::Splat2DGrad;

static_assert(sizeof(Splat2D<float>) == splat::kSplatScalars * sizeof(float), "Splat2D must pack into scalars");
static_assert(sizeof(Splat2D<double>) == splat::kSplatScalars * sizeof(double), "Splat2D must pack into scalars");
static_assert(sizeof(Splat2DGrad<float>) == splat::kGradScalars * sizeof(float), "Splat2DGrad must pack");
static_assert(sizeof(Splat2DGrad<double>) == splat::kGradScalars * sizeof(double), "Splat2DGrad must pack");
static_assert(sizeof(PixelBox) == 4 * sizeof(int32_t), "PixelBox must pack into 4 int32");

namespace {

// The rasterizer's work is split over LibTorch's intra-op thread count (tiles, which differ a
// lot in cost, one by one).
void parallel_range(int64_t n, int64_t grain, const std::function<void(int64_t, int64_t)>& fn) {
  ii::parallel_range(n, grain, at::get_num_threads(), fn);
}

void parallel_dynamic(int64_t n, const std::function<void(int64_t)>& fn) {
  ii::parallel_dynamic(n, at::get_num_threads(), fn);
}

constexpr int kTilePixels = kTileSize * kTileSize;

// Stable LSD radix sort of (key, value) pairs by key: depth order with ties by index,
// independent of threads.
void radix_sort(std::vector<uint32_t>& keys, std::vector<int32_t>& values) {
  const size_t n = keys.size();
  std::vector<uint32_t> k2(n);
  std::vector<int32_t> v2(n);
  for (int shift = 0; shift < 32; shift += 8) {
    size_t count[257] = {0};
    for (size_t i = 0; i < n; ++i) ++count[((keys[i] >> shift) & 0xffu) + 1];
    bool single = false;
    for (int d = 0; d < 256; ++d)
      if (count[d + 1] == n) single = true;
    if (single) continue;  // every key has the same digit: the pass would not move anything
    for (int d = 0; d < 256; ++d) count[d + 1] += count[d];
    for (size_t i = 0; i < n; ++i) {
      const size_t pos = count[(keys[i] >> shift) & 0xffu]++;
      k2[pos] = keys[i];
      v2[pos] = values[i];
    }
    keys.swap(k2);
    values.swap(v2);
  }
}

uint32_t depth_key(float z) {
  // z >= near > 0: the bit pattern of a positive float orders like the float.
  uint32_t bits;
  std::memcpy(&bits, &z, sizeof bits);
  return bits;
}

template <typename S>
void project_all(const CameraParams& cam, const RasterInputs& in, Splat2D<S>* splats, PixelBox* boxes) {
  const int64_t n = in.means.size(0);
  const S* means = in.means.data_ptr<S>();
  const S* quats = in.quats.data_ptr<S>();
  const S* scales = in.scales.data_ptr<S>();
  const S* opac = in.opacities.data_ptr<S>();
  const S* colors = in.colors.data_ptr<S>();
  const int64_t cstride = in.sh_degree < 0 ? 3 : int64_t(in.num_coeffs) * 3;
  const splat::ViewConsts<S> view = splat::view_consts<S>(cam);
  parallel_range(n, 2048, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) {
      if (!splat::project_gaussian(view, means + i * 3, quats + i * 4, scales + i * 3, opac[i], colors + i * cstride,
                                   in.sh_degree, in.num_coeffs, splats[i], boxes[i]))
        boxes[i] = PixelBox{};
    }
  });
}

// Per tile, the ids of the Gaussians whose box touches it, front to back (ties by id).
void bin_tiles(const CameraParams& cam, const Splat2D<float>* sf, const Splat2D<double>* sd, const PixelBox* boxes,
               int64_t n, RasterState& st) {
  std::vector<uint32_t> keys;
  std::vector<int32_t> ids;
  for (int64_t i = 0; i < n; ++i) {
    if (boxes[i].empty()) continue;
    keys.push_back(depth_key(sf ? sf[i].depth : static_cast<float>(sd[i].depth)));
    ids.push_back(static_cast<int32_t>(i));
  }
  radix_sort(keys, ids);

  // Counting sort by tile over fixed chunks of the depth order, in parallel: each tile's
  // list is the chunks' parts in chunk order, i.e. depth order, whatever the threads.
  const int tw = cam.tiles_x(), tiles = tw * cam.tiles_y();
  const int64_t nvis = static_cast<int64_t>(ids.size());
  const int64_t chunks = std::max<int64_t>(1, std::min<int64_t>(32, nvis / 4096));
  std::vector<int64_t> counts(static_cast<size_t>(chunks * tiles), 0);
  auto chunk_range = [&](int64_t c) { return std::make_pair(nvis * c / chunks, nvis * (c + 1) / chunks); };
  parallel_range(chunks, 1, [&](int64_t c0, int64_t c1) {
    for (int64_t c = c0; c < c1; ++c) {
      int64_t* cnt = counts.data() + c * tiles;
      const auto [b, e] = chunk_range(c);
      for (int64_t i = b; i < e; ++i) {
        const splat::TileRect r = splat::tile_rect(boxes[ids[i]]);
        for (int ty = r.y0; ty < r.y1; ++ty)
          for (int tx = r.x0; tx < r.x1; ++tx) ++cnt[ty * tw + tx];
      }
    }
  });
  st.tile_offsets = torch::empty({tiles + 1}, torch::kInt64);
  int64_t* off = st.tile_offsets.data_ptr<int64_t>();
  int64_t total = 0;
  for (int t = 0; t < tiles; ++t) {
    off[t] = total;
    for (int64_t c = 0; c < chunks; ++c) {
      const int64_t k = counts[c * tiles + t];
      counts[c * tiles + t] = total;  // becomes the chunk's write cursor for this tile
      total += k;
    }
  }
  off[tiles] = total;
  st.tile_gaussians = torch::empty({total}, torch::kInt32);
  int32_t* list = st.tile_gaussians.data_ptr<int32_t>();
  parallel_range(chunks, 1, [&](int64_t c0, int64_t c1) {
    for (int64_t c = c0; c < c1; ++c) {
      int64_t* cursor = counts.data() + c * tiles;
      const auto [b, e] = chunk_range(c);
      for (int64_t i = b; i < e; ++i) {
        const int32_t g = ids[i];
        const splat::TileRect r = splat::tile_rect(boxes[g]);
        for (int ty = r.y0; ty < r.y1; ++ty)
          for (int tx = r.x0; tx < r.x1; ++tx) list[cursor[ty * tw + tx]++] = g;
      }
    }
  });
}

// The tile loops for float on CPUs with AVX2 (raster_tiles.h); the scalar ones otherwise.
bool vectorised_tiles() { return cpu_features().has(CpuIsa::Avx2); }

TileBounds tile_bounds(const CameraParams& cam, const int64_t* off, int64_t tile) {
  const int tw = cam.tiles_x();
  TileBounds b;
  b.x0 = static_cast<int>(tile % tw) * kTileSize;
  b.y0 = static_cast<int>(tile / tw) * kTileSize;
  b.x1 = std::min(b.x0 + kTileSize, cam.width);
  b.y1 = std::min(b.y0 + kTileSize, cam.height);
  b.start = off[tile];
  b.end = off[tile + 1];
  return b;
}

template <typename S>
void raster_forward(const CameraParams& cam, const Splat2D<S>* splats, const PixelBox* boxes, RasterState& st,
                    S* rgb, S* alpha, S* depth) {
  const int64_t* off = st.tile_offsets.data_ptr<int64_t>();
  const int32_t* list = st.tile_gaussians.data_ptr<int32_t>();
  int32_t* last_out = st.last.data_ptr<int32_t>();
  S* final_T = st.final_T.data_ptr<S>();
  const S bg[3] = {S(cam.background[0]), S(cam.background[1]), S(cam.background[2])};
  const S t_min = S(splat::kTransmittanceMin);
  const int64_t tiles = st.tile_offsets.numel() - 1;
  if constexpr (std::is_same_v<S, float>) {
    if (vectorised_tiles()) {
      const TileForwardIo io{splats, boxes, list, cam.width, {bg[0], bg[1], bg[2]}, rgb, alpha, depth, final_T, last_out};
      parallel_dynamic(tiles, [&](int64_t tile) { forward_tile_avx2(io, tile_bounds(cam, off, tile)); });
      return;
    }
  }

  parallel_dynamic(tiles, [&](int64_t tile) {
    const TileBounds tb = tile_bounds(cam, off, tile);
    S T[kTilePixels], acc[kTilePixels][3], accd[kTilePixels];
    int32_t last[kTilePixels];
    bool done[kTilePixels];
    for (int p = 0; p < kTilePixels; ++p) {
      T[p] = 1;
      acc[p][0] = acc[p][1] = acc[p][2] = accd[p] = 0;
      last[p] = -1;
      done[p] = false;
    }
    const int npix = (tb.x1 - tb.x0) * (tb.y1 - tb.y0);
    int ndone = 0;
    for (int64_t k = tb.start; k < tb.end && ndone < npix; ++k) {
      const int32_t g = list[k];
      const Splat2D<S>& s = splats[g];
      const PixelBox& b = boxes[g];
      const int px0 = std::max(b.x0, tb.x0), px1 = std::min(b.x1, tb.x1);
      const int py0 = std::max(b.y0, tb.y0), py1 = std::min(b.y1, tb.y1);
      const int32_t rel = static_cast<int32_t>(k - tb.start);
      for (int py = py0; py < py1; ++py) {
        const S fy = S(py) + S(0.5);
        int rx0, rx1;
        splat::row_span(s, fy, rx0, rx1);
        rx0 = std::max(rx0, px0);
        rx1 = std::min(rx1, px1);
        for (int px = rx0; px < rx1; ++px) {
          const int p = (py - tb.y0) * kTileSize + (px - tb.x0);
          if (done[p]) continue;
          S dx, dy, vis, raw;
          const S a = splat::splat_alpha(s, S(px) + S(0.5), fy, dx, dy, vis, raw);
          if (a == S(0)) continue;
          const S next_T = T[p] * (S(1) - a);
          if (next_T <= t_min) {  // gsplat: the splat that would end the pixel is not added
            done[p] = true;
            ++ndone;
            continue;
          }
          const S w = a * T[p];
          acc[p][0] += s.rgb[0] * w;
          acc[p][1] += s.rgb[1] * w;
          acc[p][2] += s.rgb[2] * w;
          accd[p] += s.depth * w;
          T[p] = next_T;
          last[p] = rel;
        }
      }
    }
    for (int py = tb.y0; py < tb.y1; ++py)
      for (int px = tb.x0; px < tb.x1; ++px) {
        const int p = (py - tb.y0) * kTileSize + (px - tb.x0);
        const int64_t o = int64_t(py) * cam.width + px;
        for (int c = 0; c < 3; ++c) rgb[o * 3 + c] = acc[p][c] + T[p] * bg[c];
        const S a = S(1) - T[p];
        alpha[o] = a;
        depth[o] = accd[p] / std::max(a, S(1e-10));
        final_T[o] = T[p];
        last_out[o] = last[p];
      }
  });
}

template <typename S>
RasterOutputs forward_impl(const CameraParams& cam, const RasterInputs& in, RasterState& st) {
  const auto opts = in.means.options();
  const int64_t n = in.means.size(0);
  st.splats = torch::empty({n, splat::kSplatScalars}, opts);
  st.boxes = torch::empty({n, 4}, torch::kInt32);
  auto* splats = reinterpret_cast<Splat2D<S>*>(st.splats.data_ptr<S>());
  auto* boxes = reinterpret_cast<PixelBox*>(st.boxes.data_ptr<int32_t>());
  project_all<S>(cam, in, splats, boxes);
  if constexpr (std::is_same_v<S, float>)
    bin_tiles(cam, splats, nullptr, boxes, n, st);
  else
    bin_tiles(cam, nullptr, splats, boxes, n, st);

  RasterOutputs out;
  out.rgb = torch::empty({cam.height, cam.width, 3}, opts);
  out.alpha = torch::empty({cam.height, cam.width, 1}, opts);
  out.depth = torch::empty({cam.height, cam.width, 1}, opts);
  st.last = torch::empty({cam.height, cam.width}, torch::kInt32);
  st.final_T = torch::empty({cam.height, cam.width}, opts);
  raster_forward<S>(cam, splats, boxes, st, out.rgb.data_ptr<S>(), out.alpha.data_ptr<S>(),
                    out.depth.data_ptr<S>());
  return out;
}

// Per-tile backward: walks each pixel's contributors back to front from its final
// transmittance and writes, for every (tile, Gaussian) entry, that tile's share of the
// Gaussian's 2D gradient. Entries are summed per Gaussian afterwards in tile order, so
// the result does not depend on the thread count.
template <typename S>
void raster_backward(const CameraParams& cam, const Splat2D<S>* splats, const PixelBox* boxes,
                     const RasterState& st, const S* alpha_out, const S* depth_out, const S* g_rgb, const S* g_alpha,
                     const S* g_depth, Splat2DGrad<S>* entry_grads) {
  const int64_t* off = st.tile_offsets.data_ptr<int64_t>();
  const int32_t* list = st.tile_gaussians.data_ptr<int32_t>();
  const int32_t* last_in = st.last.data_ptr<int32_t>();
  const S* final_T = st.final_T.data_ptr<S>();
  const S bg[3] = {S(cam.background[0]), S(cam.background[1]), S(cam.background[2])};
  const int64_t tiles = st.tile_offsets.numel() - 1;
  if constexpr (std::is_same_v<S, float>) {
    if (vectorised_tiles()) {
      const TileBackwardIo io{splats, boxes, list, cam.width, {bg[0], bg[1], bg[2]}, alpha_out, depth_out, final_T,
                              last_in, g_rgb, g_alpha, g_depth, entry_grads};
      parallel_dynamic(tiles, [&](int64_t tile) { backward_tile_avx2(io, tile_bounds(cam, off, tile)); });
      return;
    }
  }

  parallel_dynamic(tiles, [&](int64_t tile) {
    const TileBounds tb = tile_bounds(cam, off, tile);
    for (int64_t k = tb.start; k < tb.end; ++k) entry_grads[k] = Splat2DGrad<S>{};
    if (tb.start == tb.end) return;
    S T[kTilePixels], T_end[kTilePixels], Sc[kTilePixels][3], Sd[kTilePixels];
    S gC[kTilePixels][3], gD[kTilePixels], gA[kTilePixels];
    int32_t last[kTilePixels];
    int32_t kmax = -1;
    for (int p = 0; p < kTilePixels; ++p) last[p] = -1;
    for (int py = tb.y0; py < tb.y1; ++py)
      for (int px = tb.x0; px < tb.x1; ++px) {
        const int p = (py - tb.y0) * kTileSize + (px - tb.x0);
        const int64_t o = int64_t(py) * cam.width + px;
        last[p] = last_in[o];
        kmax = std::max(kmax, last[p]);
        T[p] = T_end[p] = final_T[o];
        for (int c = 0; c < 3; ++c) {
          Sc[p][c] = T_end[p] * bg[c];
          gC[p][c] = g_rgb ? g_rgb[o * 3 + c] : S(0);
        }
        Sd[p] = 0;
        // depth = D / max(alpha, 1e-10): gradient to D, and to alpha through the division.
        const S a = alpha_out[o];
        const S gd = g_depth ? g_depth[o] : S(0);
        gD[p] = gd / std::max(a, S(1e-10));
        gA[p] = (g_alpha ? g_alpha[o] : S(0)) - (a > S(1e-10) ? gd * depth_out[o] / a : S(0));
      }

    for (int64_t k = tb.start + kmax; k >= tb.start; --k) {
      const int32_t g = list[k];
      const Splat2D<S>& s = splats[g];
      const PixelBox& b = boxes[g];
      const int px0 = std::max(b.x0, tb.x0), px1 = std::min(b.x1, tb.x1);
      const int py0 = std::max(b.y0, tb.y0), py1 = std::min(b.y1, tb.y1);
      const int32_t rel = static_cast<int32_t>(k - tb.start);
      Splat2DGrad<S> acc{};
      for (int py = py0; py < py1; ++py) {
        const S fy = S(py) + S(0.5);
        int rx0, rx1;
        splat::row_span(s, fy, rx0, rx1);
        rx0 = std::max(rx0, px0);
        rx1 = std::min(rx1, px1);
        for (int px = rx0; px < rx1; ++px) {
          const int p = (py - tb.y0) * kTileSize + (px - tb.x0);
          if (rel > last[p]) continue;
          S dx, dy, vis, raw;
          const S a = splat::splat_alpha(s, S(px) + S(0.5), fy, dx, dy, vis, raw);
          if (a == S(0)) continue;
          const S ra = S(1) / (S(1) - a);
          const S Ti = T[p] * ra;  // transmittance in front of this splat
          const S w = a * Ti;
          S v_alpha = gA[p] * T_end[p] * ra;
          for (int c = 0; c < 3; ++c) {
            acc.rgb[c] += gC[p][c] * w;
            v_alpha += gC[p][c] * (s.rgb[c] * Ti - Sc[p][c] * ra);
            Sc[p][c] += s.rgb[c] * w;
          }
          acc.depth += gD[p] * w;
          v_alpha += gD[p] * (s.depth * Ti - Sd[p] * ra);
          Sd[p] += s.depth * w;
          T[p] = Ti;
          if (raw <= S(splat::kAlphaMax)) {  // alpha not clamped at 0.999
            acc.opacity += v_alpha * vis;
            const S v_sigma = -v_alpha * a;
            acc.A += v_sigma * S(0.5) * dx * dx;
            acc.B += v_sigma * dx * dy;
            acc.C += v_sigma * S(0.5) * dy * dy;
            acc.mx += v_sigma * (s.A * dx + s.B * dy);
            acc.my += v_sigma * (s.B * dx + s.C * dy);
          }
        }
      }
      entry_grads[k] = acc;
    }
  });
}

template <typename S>
RasterGrads backward_impl(const CameraParams& cam, const RasterInputs& in, const RasterState& st,
                          const RasterOutputs& out, const torch::Tensor& grad_rgb, const torch::Tensor& grad_alpha,
                          const torch::Tensor& grad_depth) {
  const int64_t n = in.means.size(0);
  const auto* splats = reinterpret_cast<const Splat2D<S>*>(st.splats.data_ptr<S>());
  const auto* boxes = reinterpret_cast<const PixelBox*>(st.boxes.data_ptr<int32_t>());
  auto ptr = [](const torch::Tensor& t) -> const S* {
    return t.defined() ? t.data_ptr<S>() : nullptr;
  };

  const int64_t m = st.tile_gaussians.numel();
  // Every entry is written by raster_backward: no initialisation here.
  std::unique_ptr<Splat2DGrad<S>[]> entry_grads(new Splat2DGrad<S>[static_cast<size_t>(std::max<int64_t>(m, 1))]);
  static_assert(std::is_trivially_default_constructible_v<Splat2DGrad<S>>);
  raster_backward<S>(cam, splats, boxes, st, out.alpha.data_ptr<S>(), out.depth.data_ptr<S>(), ptr(grad_rgb),
                     ptr(grad_alpha), ptr(grad_depth), entry_grads.get());

  // Group the entries by Gaussian (counting sort; entries stay in tile order).
  const int32_t* list = st.tile_gaussians.data_ptr<int32_t>();
  std::vector<int64_t> goff(static_cast<size_t>(n) + 1, 0);
  for (int64_t k = 0; k < m; ++k) ++goff[list[k] + 1];
  for (int64_t i = 0; i < n; ++i) goff[i + 1] += goff[i];
  std::vector<int64_t> gentries(static_cast<size_t>(m));
  {
    std::vector<int64_t> cursor(goff.begin(), goff.end() - 1);
    for (int64_t k = 0; k < m; ++k) gentries[cursor[list[k]]++] = k;
  }

  RasterGrads gr;
  gr.means = torch::zeros_like(in.means);
  gr.quats = torch::zeros_like(in.quats);
  gr.scales = torch::zeros_like(in.scales);
  gr.opacities = torch::zeros_like(in.opacities);
  gr.colors = torch::zeros_like(in.colors);
  const S* means = in.means.data_ptr<S>();
  const S* quats = in.quats.data_ptr<S>();
  const S* scales = in.scales.data_ptr<S>();
  const S* colors = in.colors.data_ptr<S>();
  S* v_means = gr.means.data_ptr<S>();
  S* v_quats = gr.quats.data_ptr<S>();
  S* v_scales = gr.scales.data_ptr<S>();
  S* v_opac = gr.opacities.data_ptr<S>();
  S* v_colors = gr.colors.data_ptr<S>();
  const int64_t cstride = in.sh_degree < 0 ? 3 : int64_t(in.num_coeffs) * 3;
  const splat::ViewConsts<S> view = splat::view_consts<S>(cam);
  parallel_range(n, 1024, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) {
      if (goff[i] == goff[i + 1]) continue;
      Splat2DGrad<S> g{};
      S* gs = reinterpret_cast<S*>(&g);
      for (int64_t j = goff[i]; j < goff[i + 1]; ++j) {
        const S* eg = reinterpret_cast<const S*>(&entry_grads[gentries[j]]);
        for (int c = 0; c < splat::kGradScalars; ++c) gs[c] += eg[c];
      }
      bool any = false;
      for (int c = 0; c < splat::kGradScalars; ++c) any = any || gs[c] != S(0);
      if (!any) continue;  // hidden behind others everywhere: nothing to propagate
      splat::project_gaussian_vjp(view, means + i * 3, quats + i * 4, scales + i * 3, colors + i * cstride,
                                  in.sh_degree, g, v_means + i * 3, v_quats + i * 4, v_scales + i * 3, v_opac + i,
                                  v_colors + i * cstride);
    }
  });
  return gr;
}

}  // namespace

RasterOutputs cpu_forward(const CameraParams& cam, const RasterInputs& in, RasterState* state) {
  RasterState local;
  RasterState& st = state ? *state : local;
  if (in.means.scalar_type() == torch::kFloat64) return forward_impl<double>(cam, in, st);
  return forward_impl<float>(cam, in, st);
}

RasterGrads cpu_backward(const CameraParams& cam, const RasterInputs& in, const RasterState& state,
                         const RasterOutputs& out, const torch::Tensor& grad_rgb, const torch::Tensor& grad_alpha,
                         const torch::Tensor& grad_depth) {
  auto prep = [&](const torch::Tensor& g) {
    return g.defined() ? g.to(in.means.scalar_type()).contiguous() : g;
  };
  if (in.means.scalar_type() == torch::kFloat64)
    return backward_impl<double>(cam, in, state, out, prep(grad_rgb), prep(grad_alpha), prep(grad_depth));
  return backward_impl<float>(cam, in, state, out, prep(grad_rgb), prep(grad_alpha), prep(grad_depth));
}

}  // namespace ii::render_detail
