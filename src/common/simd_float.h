#pragma once
// Float vectors for code compiled for one instruction set (the network's CPU kernels, the
// rasterizer's tiles): one struct per set, each defined only where the including file is
// compiled for that set:
//   W      float lanes of a vector F
//   zero set1 load store add sub mul max fmadd fmsub hmax hsum exp2   float arithmetic
// Everything is in an anonymous namespace: every including file gets its own copy, compiled
// for its instruction set (an inline function with external linkage compiled for AVX-512
// could be the copy the linker keeps for callers on any CPU).
#include <immintrin.h>

namespace ii::simd {
namespace {

// 2^f for f in [-0.5, 0.5]: Taylor coefficients of exp(f ln 2), Horner form.
template <class Isa, int Degree>
inline typename Isa::F exp2_fraction(typename Isa::F f) {
  constexpr float c[] = {1.0f, 0.693147181f, 0.240226507f, 0.0555041087f, 0.00961812911f, 0.00133335581f,
                         0.000154035304f};
  static_assert(Degree >= 2 && Degree <= 6, "2^f polynomial degree");
  typename Isa::F p = Isa::set1(c[Degree]);
#pragma GCC unroll 8
  for (int i = Degree - 1; i >= 0; --i) p = Isa::fmadd(p, f, Isa::set1(c[i]));
  return p;
}

#if defined(__AVX512F__)
struct Avx512Float {
  static constexpr int W = 16;
  using F = __m512;
  static F zero() { return _mm512_setzero_ps(); }
  static F set1(float x) { return _mm512_set1_ps(x); }
  static F load(const float* p) { return _mm512_loadu_ps(p); }
  static void store(float* p, F v) { _mm512_storeu_ps(p, v); }
  static F add(F a, F b) { return _mm512_add_ps(a, b); }
  static F sub(F a, F b) { return _mm512_sub_ps(a, b); }
  static F mul(F a, F b) { return _mm512_mul_ps(a, b); }
  static F max(F a, F b) { return _mm512_max_ps(a, b); }
  static F fmadd(F a, F b, F c) { return _mm512_fmadd_ps(a, b, c); }
  static F fmsub(F a, F b, F c) { return _mm512_fmsub_ps(a, b, c); }
  static float hmax(F v) { return _mm512_reduce_max_ps(v); }
  static float hsum(F v) { return _mm512_reduce_add_ps(v); }
  // 2^t, t clamped at -100 (2^-100 is nothing beside the row maximum's 1).
  template <int Degree>
  static F exp2(F t) {
    t = _mm512_max_ps(t, set1(-100.0f));
    const F n = _mm512_roundscale_ps(t, _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
    return _mm512_scalef_ps(exp2_fraction<Avx512Float, Degree>(_mm512_sub_ps(t, n)), n);
  }
};

#endif

#if defined(__AVX2__) && defined(__FMA__)
struct Avx2Float {
  static constexpr int W = 8;
  using F = __m256;
  static F zero() { return _mm256_setzero_ps(); }
  static F set1(float x) { return _mm256_set1_ps(x); }
  static F load(const float* p) { return _mm256_loadu_ps(p); }
  static void store(float* p, F v) { _mm256_storeu_ps(p, v); }
  static F add(F a, F b) { return _mm256_add_ps(a, b); }
  static F sub(F a, F b) { return _mm256_sub_ps(a, b); }
  static F mul(F a, F b) { return _mm256_mul_ps(a, b); }
  static F max(F a, F b) { return _mm256_max_ps(a, b); }
  static F fmadd(F a, F b, F c) { return _mm256_fmadd_ps(a, b, c); }
  static F fmsub(F a, F b, F c) { return _mm256_fmsub_ps(a, b, c); }
  static float hmax(F v) {
    __m128 m = _mm_max_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps(v, 1));
    m = _mm_max_ps(m, _mm_movehl_ps(m, m));
    return _mm_cvtss_f32(_mm_max_ss(m, _mm_movehdup_ps(m)));
  }
  static float hsum(F v) {
    __m128 s = _mm_add_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps(v, 1));
    s = _mm_add_ps(s, _mm_movehl_ps(s, s));
    return _mm_cvtss_f32(_mm_add_ss(s, _mm_movehdup_ps(s)));
  }
  // 2^t, t clamped at -100; 2^n is added to the exponent bits (no scalef before AVX-512).
  template <int Degree>
  static F exp2(F t) {
    t = _mm256_max_ps(t, set1(-100.0f));
    const F n = _mm256_round_ps(t, _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
    const F p = exp2_fraction<Avx2Float, Degree>(_mm256_sub_ps(t, n));
    return _mm256_castsi256_ps(
        _mm256_add_epi32(_mm256_castps_si256(p), _mm256_slli_epi32(_mm256_cvtps_epi32(n), 23)));
  }
};

#endif

}  // namespace
}  // namespace ii::simd
