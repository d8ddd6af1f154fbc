// The CPU attention kernel for AMX (flags: CMakeLists.txt; chosen at run time, see kernels.h):
// attention_amx_impl.h on the tiles, its softmax in AVX-512 BF16.
#include <immintrin.h>

#include "model/cpu/isa.h"

namespace ii::cpu_kernels {
namespace {

// Tiles 0-3 accumulate, 4-5 hold the first operand (rows), 6-7 the second (columns); every
// tile is 16 rows of 64 bytes.
struct alignas(64) TileConfig {
  uint8_t palette = 1;
  uint8_t start_row = 0;
  uint8_t reserved[14] = {};
  uint16_t bytes_per_row[16] = {};
  uint8_t rows[16] = {};
};

void configure_tiles() {
  TileConfig config;
  for (int t = 0; t < 8; ++t) {
    config.bytes_per_row[t] = 64;
    config.rows[t] = 16;
  }
  _tile_loadconfig(&config);
}

}  // namespace
}  // namespace ii::cpu_kernels

#define II_TILE_CONFIGURE() configure_tiles()
#define II_TILE_RELEASE() _tile_release()
#define II_TILE_ZERO(t) _tile_zero(t)
#define II_TILE_LOAD(t, pointer, stride) _tile_loadd(t, pointer, stride)
#define II_TILE_STORE(t, pointer, stride) _tile_stored(t, pointer, stride)
#define II_TILE_DOT(c, a, b) _tile_dpbf16ps(c, a, b)
#include "model/cpu/attention_amx_impl.h"

namespace ii::cpu_kernels {

bool attention_amx_bf16(const AttentionProblem& problem, ParallelFor parallel) {
  return run_amx_attention<Avx512Bf16>(problem, parallel);
}

}  // namespace ii::cpu_kernels
