// The scalar per-tile loops of cpu_rasterizer.cpp, eight pixels of a tile row at a time:
// the same arithmetic lane by lane (e^x from common/simd_float.h's 2^x, 1.2e-7 relative
// error), the same pixel order per Gaussian, so the images agree with the scalar form to
// float rounding. Compiled with -mavx2 -mfma (raster_tiles.h says why it includes so little).
#include "render/cpu/raster_tiles.h"

#include <immintrin.h>

#include "common/simd_float.h"

namespace ii::render_detail {
namespace {

using V = simd::Avx2Float;
using splat::kTileSize;
constexpr int kTilePixels = kTileSize * kTileSize;
constexpr int kLanes = V::W;
static_assert(kTileSize == 2 * kLanes, "a tile row is two vectors");

int smaller(int a, int b) { return a < b ? a : b; }
int larger(int a, int b) { return a > b ? a : b; }

__m256 mask_and(__m256 mask, __m256 v) { return _mm256_and_ps(mask, v); }
bool any(__m256 mask) { return _mm256_movemask_ps(mask) != 0; }

// Lanes whose column x0 + i lies in [c0, c1).
__m256 columns_in(int x0, int c0, int c1) {
  const __m256i x = _mm256_add_epi32(_mm256_set1_epi32(x0), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
  const __m256i in = _mm256_and_si256(_mm256_cmpgt_epi32(x, _mm256_set1_epi32(c0 - 1)),
                                      _mm256_cmpgt_epi32(_mm256_set1_epi32(c1), x));
  return _mm256_castsi256_ps(in);
}

// One splat's constants as vectors.
struct SplatLanes {
  __m256 mx, A, B, C, opacity;
  float c, row_curvature, level;
  explicit SplatLanes(const splat::Splat2D<float>& s)
      : mx(V::set1(s.mx)), A(V::set1(s.A)), B(V::set1(s.B)), C(V::set1(s.C)), opacity(V::set1(s.opacity)), c(s.C),
        // sigma's minimum over a row at vertical distance dy is dy² (C - B²/A) / 2 (A > 0).
        row_curvature(0.5f * (s.C - s.B * s.B / s.A)), level(s.level) {}
  // Whether the row at vertical distance dy can reach alpha >= 1/255 (a margin far above
  // rounding: skipping a row changes nothing but speed; NaN never skips).
  bool misses_row(float dy) const { return dy * dy * row_curvature > level + 1e-3f + 1e-3f * level; }
};

// splat::splat_alpha for the 8 pixels of a row from column x0: alpha (where `ok`), and dx,
// vis, raw as the backward pass needs them. Lanes outside `ok` hold finite garbage.
struct AlphaLanes {
  __m256 dx, vis, raw, alpha, ok;
};
AlphaLanes alpha_lanes(const SplatLanes& s, int x0, float dy, __m256 candidates) {
  AlphaLanes l;
  const __m256 centres = _mm256_add_ps(_mm256_set1_ps(float(x0) + 0.5f), _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7));
  const __m256 vdy = V::set1(dy);
  l.dx = V::sub(s.mx, centres);
  const __m256 quad = V::add(V::mul(V::mul(s.A, l.dx), l.dx), V::set1(s.c * dy * dy));
  const __m256 sigma = V::add(V::mul(V::set1(0.5f), quad), V::mul(V::mul(s.B, l.dx), vdy));
  // e^-sigma; lanes with sigma < 0 are dropped below, so the exponent is capped at 0 there.
  const __m256 exponent = _mm256_min_ps(V::mul(sigma, V::set1(-1.44269504088896341f)), V::zero());
  l.vis = V::exp2<6>(exponent);
  l.raw = V::mul(s.opacity, l.vis);
  l.alpha = _mm256_min_ps(V::set1(float(splat::kAlphaMax)), l.raw);
  l.ok = _mm256_and_ps(candidates, _mm256_and_ps(_mm256_cmp_ps(sigma, V::zero(), _CMP_GE_OQ),
                                                  _mm256_cmp_ps(l.alpha, V::set1(float(splat::kAlphaMin)), _CMP_GE_OQ)));
  return l;
}

// The column range [c0, c1) and row range [r0, r1) where the splat's box meets the tile.
struct Overlap {
  int c0, c1, r0, r1;
};
Overlap overlap(const splat::PixelBox& b, const TileBounds& t) {
  return {larger(b.x0, t.x0), smaller(b.x1, t.x1), larger(b.y0, t.y0), smaller(b.y1, t.y1)};
}

}  // namespace

void forward_tile_avx2(const TileForwardIo& io, const TileBounds& tile) {
  alignas(32) float T[kTilePixels], acc_r[kTilePixels], acc_g[kTilePixels], acc_b[kTilePixels], acc_d[kTilePixels];
  alignas(32) int32_t last[kTilePixels], done[kTilePixels];
  for (int p = 0; p < kTilePixels; p += kLanes) {
    V::store(T + p, V::set1(1));
    V::store(acc_r + p, V::zero());
    V::store(acc_g + p, V::zero());
    V::store(acc_b + p, V::zero());
    V::store(acc_d + p, V::zero());
    _mm256_store_si256(reinterpret_cast<__m256i*>(last + p), _mm256_set1_epi32(-1));
    _mm256_store_si256(reinterpret_cast<__m256i*>(done + p), _mm256_setzero_si256());
  }
  const __m256 t_min = V::set1(float(splat::kTransmittanceMin)), one = V::set1(1);
  const int npix = (tile.x1 - tile.x0) * (tile.y1 - tile.y0);
  int ndone = 0;
  for (int64_t k = tile.start; k < tile.end && ndone < npix; ++k) {
    const int32_t id = io.tile_gaussians[k];
    const splat::Splat2D<float>& s = io.splats[id];
    const Overlap o = overlap(io.boxes[id], tile);
    const SplatLanes sl(s);
    const __m256 rel = _mm256_castsi256_ps(_mm256_set1_epi32(static_cast<int32_t>(k - tile.start)));
    const __m256 r = V::set1(s.rgb[0]), g = V::set1(s.rgb[1]), b = V::set1(s.rgb[2]), d = V::set1(s.depth);
    for (int py = o.r0; py < o.r1; ++py) {
      const float dy = s.my - (float(py) + 0.5f);
      if (sl.misses_row(dy)) continue;
      for (int x0 = tile.x0; x0 < tile.x0 + kTileSize; x0 += kLanes) {
        if (x0 >= o.c1 || x0 + kLanes <= o.c0) continue;
        const int p = (py - tile.y0) * kTileSize + (x0 - tile.x0);
        const __m256 was_done = _mm256_load_ps(reinterpret_cast<const float*>(done + p));
        const AlphaLanes l = alpha_lanes(sl, x0, dy, _mm256_andnot_ps(was_done, columns_in(x0, o.c0, o.c1)));
        if (!any(l.ok)) continue;
        const __m256 t = V::load(T + p);
        const __m256 next_T = V::mul(t, V::sub(one, l.alpha));
        // gsplat: the splat that would end the pixel is not added.
        const __m256 ends = _mm256_and_ps(l.ok, _mm256_cmp_ps(next_T, t_min, _CMP_LE_OQ));
        if (any(ends)) {
          _mm256_store_ps(reinterpret_cast<float*>(done + p), _mm256_or_ps(was_done, ends));
          ndone += __builtin_popcount(static_cast<unsigned>(_mm256_movemask_ps(ends)));
        }
        const __m256 adds = _mm256_andnot_ps(ends, l.ok);
        const __m256 w = mask_and(adds, V::mul(l.alpha, t));
        V::store(acc_r + p, V::add(V::load(acc_r + p), V::mul(r, w)));
        V::store(acc_g + p, V::add(V::load(acc_g + p), V::mul(g, w)));
        V::store(acc_b + p, V::add(V::load(acc_b + p), V::mul(b, w)));
        V::store(acc_d + p, V::add(V::load(acc_d + p), V::mul(d, w)));
        V::store(T + p, _mm256_blendv_ps(t, next_T, adds));
        float* lp = reinterpret_cast<float*>(last + p);
        _mm256_store_ps(lp, _mm256_blendv_ps(_mm256_load_ps(lp), rel, adds));
      }
    }
  }
  for (int py = tile.y0; py < tile.y1; ++py)
    for (int px = tile.x0; px < tile.x1; ++px) {
      const int p = (py - tile.y0) * kTileSize + (px - tile.x0);
      const int64_t o = int64_t(py) * io.width + px;
      io.rgb[o * 3 + 0] = acc_r[p] + T[p] * io.background[0];
      io.rgb[o * 3 + 1] = acc_g[p] + T[p] * io.background[1];
      io.rgb[o * 3 + 2] = acc_b[p] + T[p] * io.background[2];
      const float a = 1 - T[p];
      io.alpha[o] = a;
      io.depth[o] = acc_d[p] / (a > 1e-10f ? a : 1e-10f);
      io.final_T[o] = T[p];
      io.last[o] = last[p];
    }
}

void backward_tile_avx2(const TileBackwardIo& io, const TileBounds& tile) {
  for (int64_t k = tile.start; k < tile.end; ++k) io.entry_grads[k] = splat::Splat2DGrad<float>{};
  if (tile.start == tile.end) return;
  // Per pixel: transmittance (walked back from the end), what lies behind (colour, depth),
  // the gradients of its colour, depth and alpha. Pixels outside the image keep last = -1.
  alignas(32) float T[kTilePixels] = {}, T_end[kTilePixels] = {}, behind_r[kTilePixels] = {},
                    behind_g[kTilePixels] = {}, behind_b[kTilePixels] = {}, behind_d[kTilePixels] = {},
                    g_r[kTilePixels] = {}, g_g[kTilePixels] = {}, g_b[kTilePixels] = {}, g_d[kTilePixels] = {},
                    g_a[kTilePixels] = {};
  alignas(32) int32_t last[kTilePixels];
  for (int p = 0; p < kTilePixels; ++p) last[p] = -1;
  int32_t kmax = -1;
  for (int py = tile.y0; py < tile.y1; ++py)
    for (int px = tile.x0; px < tile.x1; ++px) {
      const int p = (py - tile.y0) * kTileSize + (px - tile.x0);
      const int64_t o = int64_t(py) * io.width + px;
      last[p] = io.last[o];
      kmax = larger(kmax, last[p]);
      T[p] = T_end[p] = io.final_T[o];
      behind_r[p] = T_end[p] * io.background[0];
      behind_g[p] = T_end[p] * io.background[1];
      behind_b[p] = T_end[p] * io.background[2];
      if (io.grad_rgb) {
        g_r[p] = io.grad_rgb[o * 3 + 0];
        g_g[p] = io.grad_rgb[o * 3 + 1];
        g_b[p] = io.grad_rgb[o * 3 + 2];
      }
      // depth = D / max(alpha, 1e-10): gradient to D, and to alpha through the division.
      const float a = io.alpha[o];
      const float gd = io.grad_depth ? io.grad_depth[o] : 0.0f;
      g_d[p] = gd / (a > 1e-10f ? a : 1e-10f);
      g_a[p] = (io.grad_alpha ? io.grad_alpha[o] : 0.0f) - (a > 1e-10f ? gd * io.depth[o] / a : 0.0f);
    }

  const __m256 one = V::set1(1), half = V::set1(0.5f);
  // splat_alpha clamps at kAlphaMax in float; the scalar form compares raw with the double.
  const __m256 raw_max = V::set1(__builtin_nextafterf(float(splat::kAlphaMax), 0.0f));
  for (int64_t k = tile.start + kmax; k >= tile.start; --k) {
    const int32_t id = io.tile_gaussians[k];
    const splat::Splat2D<float>& s = io.splats[id];
    const Overlap o = overlap(io.boxes[id], tile);
    const SplatLanes sl(s);
    const __m256i rel_minus_one = _mm256_set1_epi32(static_cast<int32_t>(k - tile.start) - 1);
    const __m256 r = V::set1(s.rgb[0]), g = V::set1(s.rgb[1]), b = V::set1(s.rgb[2]), d = V::set1(s.depth);
    __m256 v_r = V::zero(), v_g = V::zero(), v_b = V::zero(), v_d = V::zero(), v_opacity = V::zero();
    __m256 v_A = V::zero(), v_B = V::zero(), v_C = V::zero(), v_mx = V::zero(), v_my = V::zero();
    for (int py = o.r0; py < o.r1; ++py) {
      const float dy_s = s.my - (float(py) + 0.5f);
      if (sl.misses_row(dy_s)) continue;
      const __m256 dy = V::set1(dy_s);
      for (int x0 = tile.x0; x0 < tile.x0 + kTileSize; x0 += kLanes) {
        if (x0 >= o.c1 || x0 + kLanes <= o.c0) continue;
        const int p = (py - tile.y0) * kTileSize + (x0 - tile.x0);
        // Pixels this splat reached in the forward pass: up to each one's last contributor.
        const __m256 reached = _mm256_castsi256_ps(
            _mm256_cmpgt_epi32(_mm256_load_si256(reinterpret_cast<const __m256i*>(last + p)), rel_minus_one));
        const AlphaLanes l = alpha_lanes(sl, x0, dy_s, _mm256_and_ps(reached, columns_in(x0, o.c0, o.c1)));
        if (!any(l.ok)) continue;
        const __m256 ra = _mm256_div_ps(one, V::sub(one, l.alpha));
        const __m256 t_behind = V::load(T + p);
        const __m256 t = V::mul(t_behind, ra);  // transmittance in front of this splat
        const __m256 w = V::mul(l.alpha, t);
        const __m256 wm = mask_and(l.ok, w);
        __m256 v_alpha = V::mul(V::mul(V::load(g_a + p), V::load(T_end + p)), ra);
        // Per channel: this splat's colour gradient, alpha's, and what lies behind it.
        auto channel = [&](float* behind, const float* grad, __m256 value, __m256& v_value) {
          const __m256 gc = V::load(grad + p), bc = V::load(behind + p);
          v_value = V::add(v_value, V::mul(gc, wm));
          v_alpha = V::add(v_alpha, V::mul(gc, V::sub(V::mul(value, t), V::mul(bc, ra))));
          V::store(behind + p, V::add(bc, V::mul(value, wm)));
        };
        channel(behind_r, g_r, r, v_r);
        channel(behind_g, g_g, g, v_g);
        channel(behind_b, g_b, b, v_b);
        channel(behind_d, g_d, d, v_d);
        V::store(T + p, _mm256_blendv_ps(t_behind, t, l.ok));
        // Alpha not clamped at 0.999: gradients to opacity and the conic.
        const __m256 unclamped = _mm256_and_ps(l.ok, _mm256_cmp_ps(l.raw, raw_max, _CMP_LE_OQ));
        v_opacity = V::add(v_opacity, mask_and(unclamped, V::mul(v_alpha, l.vis)));
        const __m256 v_sigma = mask_and(unclamped, V::mul(V::sub(V::zero(), v_alpha), l.alpha));
        v_A = V::add(v_A, V::mul(V::mul(V::mul(v_sigma, half), l.dx), l.dx));
        v_B = V::add(v_B, V::mul(V::mul(v_sigma, l.dx), dy));
        v_C = V::add(v_C, V::mul(V::mul(V::mul(v_sigma, half), dy), dy));
        v_mx = V::add(v_mx, V::mul(v_sigma, V::add(V::mul(sl.A, l.dx), V::mul(sl.B, dy))));
        v_my = V::add(v_my, V::mul(v_sigma, V::add(V::mul(sl.B, l.dx), V::mul(sl.C, dy))));
      }
    }
    splat::Splat2DGrad<float>& e = io.entry_grads[k];
    e.mx = V::hsum(v_mx);
    e.my = V::hsum(v_my);
    e.A = V::hsum(v_A);
    e.B = V::hsum(v_B);
    e.C = V::hsum(v_C);
    e.depth = V::hsum(v_d);
    e.opacity = V::hsum(v_opacity);
    e.rgb[0] = V::hsum(v_r);
    e.rgb[1] = V::hsum(v_g);
    e.rgb[2] = V::hsum(v_b);
  }
}

}  // namespace ii::render_detail
