#pragma once
// Vector traits for the CPU kernels (attention_impl.h, layer_norm_impl.h), one struct per
// instruction set, each defined only where the including file is compiled for that set, over
// the float vectors of common/simd_float.h (W, F, float arithmetic, exp2):
//   kPair       input elements per dot-product step: 2 for bf16 (vdpbf16ps multiplies pairs),
//               1 for float; a vector X of inputs holds W such pairs
//   In          input element storage (uint16_t bf16 bits, or float)
//   load_in / broadcast_in / madd   inputs and the dot-product step
//   load_in_f / store_in / to_in    W inputs as floats, and back (bf16: round to nearest even)
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
#include <cstdlib>

#include "common/simd_float.h"

namespace ii::cpu_kernels {
namespace {

#if defined(__AVX512F__)
using simd::Avx512Float;
#endif
#if defined(__AVX2__) && defined(__FMA__)
using simd::Avx2Float;
#endif

constexpr int64_t round_up(int64_t x, int64_t to) { return (x + to - 1) / to * to; }
inline int64_t smaller(int64_t a, int64_t b) { return a < b ? a : b; }
inline float larger(float a, float b) { return a > b ? a : b; }

// `count` elements of T on a 64-byte boundary (std::free them), or nullptr.
template <class T>
T* aligned_elements(int64_t count) {
  const size_t bytes = static_cast<size_t>(round_up(count * static_cast<int64_t>(sizeof(T)), 64));
  return static_cast<T*>(std::aligned_alloc(64, bytes > 0 ? bytes : 64));
}

// Element (b, h, 0, 0) of a kernel's tensor (kernels.h: AttentionProblem's strides).
template <class T>
T* slice_at(T* base, const int64_t* strides, int64_t b, int64_t h) {
  return base + b * strides[0] + h * strides[1];
}

// A float's bf16 bits, rounded to nearest even as LibTorch and vcvtneps2bf16 convert.
inline uint16_t bf16_bits(float x) {
  uint32_t bits;
  __builtin_memcpy(&bits, &x, sizeof(bits));
  bits += 0x7fffu + ((bits >> 16) & 1u);
  return static_cast<uint16_t>(bits >> 16);
}

#if defined(__AVX512F__)
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
  static In to_in(float x) { return bf16_bits(x); }
};
#endif

#if defined(__AVX2__) && defined(__FMA__)
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
