// A model of the AMX tile instructions that the attention kernel uses, as Intel's reference
// describes them (eight tiles of 16 rows x 64 bytes; TDPBF16PS: c[m][n] += a[m][2k] b[k][2n] +
// a[m][2k+1] b[k][2n+1] over the 16 pairs k, in float), and the kernel's loops compiled over it.
// Compiled for AVX2 (tests/CMakeLists.txt); includes nothing but the kernel's headers.
#include "amx_tile_model.h"

#include <immintrin.h>

#include "model/cpu/isa.h"

namespace ii::test {
namespace {

struct TileModel {
  static inline unsigned char tiles[8][16][64];
  static inline bool configured = false;
  static inline int64_t unconfigured_uses = 0;

  static void check() { unconfigured_uses += configured ? 0 : 1; }
  static float from_bf16(const unsigned char* bytes) {
    const uint32_t bits = static_cast<uint32_t>(bytes[0] | (bytes[1] << 8)) << 16;
    float f;
    __builtin_memcpy(&f, &bits, sizeof(f));
    return f;
  }
  static void zero(int t) {
    check();
    __builtin_memset(tiles[t], 0, sizeof(tiles[t]));
  }
  static void load(int t, const void* base, int64_t stride) {
    check();
    for (int r = 0; r < 16; ++r) __builtin_memcpy(tiles[t][r], static_cast<const char*>(base) + r * stride, 64);
  }
  static void store(int t, void* base, int64_t stride) {
    check();
    for (int r = 0; r < 16; ++r) __builtin_memcpy(static_cast<char*>(base) + r * stride, tiles[t][r], 64);
  }
  static void dot(int c, int a, int b) {
    check();
    for (int m = 0; m < 16; ++m)
      for (int n = 0; n < 16; ++n) {
        float acc;
        __builtin_memcpy(&acc, tiles[c][m] + 4 * n, 4);
        for (int k = 0; k < 16; ++k) {
          acc += from_bf16(tiles[a][m] + 4 * k) * from_bf16(tiles[b][k] + 4 * n);
          acc += from_bf16(tiles[a][m] + 4 * k + 2) * from_bf16(tiles[b][k] + 4 * n + 2);
        }
        __builtin_memcpy(tiles[c][m] + 4 * n, &acc, 4);
      }
  }
};

// The softmax's vectors in AVX2.
struct Avx2Bf16Rows : simd::Avx2Float {
  using In = uint16_t;
  static In to_in(float x) { return cpu_kernels::bf16_bits(x); }
  static void store_in(In* p, F v) {
    alignas(32) float f[W];
    _mm256_store_ps(f, v);
    for (int i = 0; i < W; ++i) p[i] = to_in(f[i]);
  }
};

}  // namespace
}  // namespace ii::test

#define II_TILE_CONFIGURE() (ii::test::TileModel::configured = true)
#define II_TILE_RELEASE() (ii::test::TileModel::configured = false)
#define II_TILE_ZERO(t) ii::test::TileModel::zero(t)
#define II_TILE_LOAD(t, pointer, stride) ii::test::TileModel::load(t, pointer, stride)
#define II_TILE_STORE(t, pointer, stride) ii::test::TileModel::store(t, pointer, stride)
#define II_TILE_DOT(c, a, b) ii::test::TileModel::dot(c, a, b)
#include "model/cpu/attention_amx_impl.h"

namespace ii::test {

bool attention_amx_bf16_on_tile_model(const cpu_kernels::AttentionProblem& problem, cpu_kernels::ParallelFor) {
  TileModel::unconfigured_uses = 0;
  auto serial = [](int64_t count, void (*task)(void*, int64_t), void* context) {
    for (int64_t i = 0; i < count; ++i) task(context, i);
  };
  return cpu_kernels::run_amx_attention<Avx2Bf16Rows>(problem, serial);
}

int64_t tile_model_unconfigured_uses() { return TileModel::unconfigured_uses; }

}  // namespace ii::test
