#pragma once
// Vector traits for the CPU kernels (attention_impl.h, layer_norm_impl.h), one struct per
// instruction set, each defined only where the including file is compiled for that set:
//   W           float lanes of a vector F
//   kPair       input elements per dot-product step: 2 for bf16 (vdpbf16ps multiplies pairs),
//               1 for float; a vector X of inputs holds W such pairs
//   In          input element storage (uint16_t bf16 bits, or float)
//   load_in / broadcast_in / madd   inputs and the dot-product step
//   load_in_f / store_in / to_in    W inputs as floats, and back (bf16: round to nearest even)
//   zero set1 load store add sub mul max fmadd fmsub hmax hsum exp2   float arithmetic
//   kScoreRows x kScoreVectors     register tile of the q·kᵀ microkernel (queries x W keys)
//   kValueRows x kValueVectors     register tile of the p·v microkernel (queries x W dims)
//   kKeyBlock   keys per block (their k and v stay in cache while a tile of queries passes)
//   kTileRows   query rows per task
//   kExpDegree  degree of the 2^f polynomial (4: 4e-5 relative error, enough for bf16
//               probabilities; 6: 1.2e-7, float)
//
// Everything is in an anonymous namespace: every including file gets its own copy, compiled
// for its instruction set (see kernels.h).
#include <immintrin.h>

#include <cstdint>

namespace ii::cpu_kernels {
namespace {

constexpr int64_t round_up(int64_t x, int64_t to) { return (x + to - 1) / to * to; }
inline int64_t smaller(int64_t a, int64_t b) { return a < b ? a : b; }
inline float larger(float a, float b) { return a > b ? a : b; }

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

// ---- float vectors -----------------------------------------------------------------------
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

struct Avx512Fp32 : Avx512Float {
  static constexpr int kPair = 1, kExpDegree = 6;
  static constexpr int kScoreRows = 12, kScoreVectors = 2, kValueRows = 6, kValueVectors = 4;
  static constexpr int64_t kKeyBlock = 512, kTileRows = 96;
  using In = float;
  using X = __m512;
  static X load_in(const In* p) { return _mm512_loadu_ps(p); }
  static X broadcast_in(const In* p) { return _mm512_set1_ps(*p); }
  static F madd(F acc, X a, X b) { return _mm512_fmadd_ps(a, b, acc); }
  static F load_in_f(const In* p) { return _mm512_loadu_ps(p); }
  static void store_in(In* p, F v) { _mm512_storeu_ps(p, v); }
  static float from_in(In x) { return x; }
  static In to_in(float x) { return x; }
};
#endif

#if defined(__AVX512BF16__)
struct Avx512Bf16 : Avx512Float {
  static constexpr int kPair = 2, kExpDegree = 4;
  static constexpr int kScoreRows = 12, kScoreVectors = 2, kValueRows = 6, kValueVectors = 4;
  static constexpr int64_t kKeyBlock = 512, kTileRows = 96;
  using In = uint16_t;  // bf16 bits
  using X = __m512i;    // 16 pairs
  static X load_in(const In* p) { return _mm512_loadu_si512(p); }
  static X broadcast_in(const In* p) {
    int32_t pair;
    __builtin_memcpy(&pair, p, sizeof(pair));
    return _mm512_set1_epi32(pair);
  }
  static F madd(F acc, X a, X b) { return _mm512_dpbf16_ps(acc, (__m512bh)a, (__m512bh)b); }
  // bf16 is the top half of a float.
  static F load_in_f(const In* p) {
    const __m512i wide = _mm512_cvtepu16_epi32(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(p)));
    return _mm512_castsi512_ps(_mm512_slli_epi32(wide, 16));
  }
  static void store_in(In* p, F v) { _mm256_storeu_si256(reinterpret_cast<__m256i*>(p), (__m256i)_mm512_cvtneps_pbh(v)); }
  static float from_in(In x) {
    const uint32_t bits = static_cast<uint32_t>(x) << 16;
    float f;
    __builtin_memcpy(&f, &bits, sizeof(f));
    return f;
  }
  // Round to nearest even, as LibTorch converts.
  static In to_in(float x) {
    uint32_t bits;
    __builtin_memcpy(&bits, &x, sizeof(bits));
    bits += 0x7fffu + ((bits >> 16) & 1u);
    return static_cast<In>(bits >> 16);
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

struct Avx2Fp32 : Avx2Float {
  static constexpr int kPair = 1, kExpDegree = 6;
  // 16 registers: 12 score accumulators + 2 k vectors + 1 broadcast; 8 value accumulators
  // + 4 v vectors + 1 broadcast (3 x 4 accumulators spill one of them, halving the speed).
  static constexpr int kScoreRows = 6, kScoreVectors = 2, kValueRows = 2, kValueVectors = 4;
  static constexpr int64_t kKeyBlock = 256, kTileRows = 96;
  using In = float;
  using X = __m256;
  static X load_in(const In* p) { return _mm256_loadu_ps(p); }
  static X broadcast_in(const In* p) { return _mm256_broadcast_ss(p); }
  static F madd(F acc, X a, X b) { return _mm256_fmadd_ps(a, b, acc); }
  static F load_in_f(const In* p) { return _mm256_loadu_ps(p); }
  static void store_in(In* p, F v) { _mm256_storeu_ps(p, v); }
  static float from_in(In x) { return x; }
  static In to_in(float x) { return x; }
};
#endif

}  // namespace
}  // namespace ii::cpu_kernels
