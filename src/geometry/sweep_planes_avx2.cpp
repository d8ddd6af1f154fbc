// sweep_planes (geometry/sweep_planes.h) compiled with -mavx2 -mfma: the warp eight pixels at a
// time, its bilinear samples by gathers (GCC does not vectorise the plain loop: its float to int
// conversions and selects stay scalar); the window sums and the correlation are the shared body's.
#include <immintrin.h>

#include "geometry/sweep_planes_body.h"

namespace ii::sweep_detail {
namespace {

void warp_avx2(const SweepIo& io, const float* depth, float* warped, float* inside, int64_t begin) {
  const int64_t n = io.height * io.width;
  const int stride = static_cast<int>(io.source_width + 2);
  const float width = static_cast<float>(io.source_width), height = static_cast<float>(io.source_height);
  const __m256 tx = _mm256_set1_ps(io.translation[0]), ty = _mm256_set1_ps(io.translation[1]),
               tz = _mm256_set1_ps(io.translation[2]);
  const __m256 fx = _mm256_set1_ps(io.fx), fy = _mm256_set1_ps(io.fy), cx = _mm256_set1_ps(io.cx),
               cy = _mm256_set1_ps(io.cy);
  const __m256 one = _mm256_set1_ps(1.f), nearest_z = _mm256_set1_ps(1e-6f), minus_one = _mm256_set1_ps(-1.f),
               minus_half = _mm256_set1_ps(-0.5f), w = _mm256_set1_ps(width), h = _mm256_set1_ps(height),
               w_half = _mm256_set1_ps(width - 0.5f), h_half = _mm256_set1_ps(height - 0.5f);
  const __m256i row_stride = _mm256_set1_epi32(stride);
  const float* source = io.bordered_source;
  auto above = [](__m256 a, __m256 b) { return _mm256_cmp_ps(a, b, _CMP_GT_OQ); };  // false for NaN
  auto at_least = [](__m256 a, __m256 b) { return _mm256_cmp_ps(a, b, _CMP_GE_OQ); };
  int64_t p = begin;
  for (; p + 8 <= n; p += 8) {
    const __m256 d = _mm256_loadu_ps(depth + p);
    const __m256 z = _mm256_fmadd_ps(d, _mm256_loadu_ps(io.ray + 2 * n + p), tz);
    const __m256 reciprocal = _mm256_div_ps(one, _mm256_max_ps(z, nearest_z));
    const __m256 u =
        _mm256_fmadd_ps(_mm256_mul_ps(_mm256_fmadd_ps(d, _mm256_loadu_ps(io.ray + p), tx), reciprocal), fx, cx);
    const __m256 v =
        _mm256_fmadd_ps(_mm256_mul_ps(_mm256_fmadd_ps(d, _mm256_loadu_ps(io.ray + n + p), ty), reciprocal), fy, cy);
    const __m256 near = _mm256_and_ps(_mm256_and_ps(above(u, minus_one), above(w, u)),
                                      _mm256_and_ps(above(v, minus_one), above(h, v)));
    const __m256 uu = _mm256_and_ps(near, _mm256_add_ps(u, one)), vv = _mm256_and_ps(near, _mm256_add_ps(v, one));
    const __m256i column = _mm256_cvttps_epi32(uu), row = _mm256_cvttps_epi32(vv);
    const __m256 ax = _mm256_sub_ps(uu, _mm256_cvtepi32_ps(column)), ay = _mm256_sub_ps(vv, _mm256_cvtepi32_ps(row));
    const __m256i at = _mm256_add_epi32(_mm256_mullo_epi32(row, row_stride), column);
    const __m256 s00 = _mm256_i32gather_ps(source, at, 4), s01 = _mm256_i32gather_ps(source + 1, at, 4);
    const __m256 s10 = _mm256_i32gather_ps(source + stride, at, 4),
                 s11 = _mm256_i32gather_ps(source + stride + 1, at, 4);
    const __m256 top = _mm256_fmadd_ps(ax, _mm256_sub_ps(s01, s00), s00);
    const __m256 bottom = _mm256_fmadd_ps(ax, _mm256_sub_ps(s11, s10), s10);
    const __m256 value = _mm256_and_ps(near, _mm256_fmadd_ps(ay, _mm256_sub_ps(bottom, top), top));
    _mm256_storeu_ps(warped + p, value);
    _mm256_storeu_ps(warped + n + p, _mm256_mul_ps(value, value));
    _mm256_storeu_ps(warped + 2 * n + p, _mm256_mul_ps(value, _mm256_loadu_ps(io.reference + p)));
    const __m256 in_picture = _mm256_and_ps(_mm256_and_ps(at_least(u, minus_half), at_least(w_half, u)),
                                            _mm256_and_ps(at_least(v, minus_half), at_least(h_half, v)));
    _mm256_storeu_ps(inside + p, _mm256_and_ps(_mm256_and_ps(above(z, nearest_z), in_picture), one));
  }
  warp(io, depth, warped, inside, p);
}

}  // namespace

void sweep_planes_avx2(const SweepIo& io, int64_t first, int64_t last, float* scratch) {
  sweep_planes_body(io, first, last, scratch, warp_avx2);
}

}  // namespace ii::sweep_detail
