#pragma once
// The AMX attention kernel (kernels_amx.cpp), written once over the operations it needs so that
// the same loops also run on a model of the tiles where the CPU has none
// (tests/model/amx_tile_model.cpp): the layouts and the blocking are what can go wrong in it.
//
// The flash-attention form of attention_impl.h with both matrix products on the AMX tiles:
// q·kᵀ and p·v as tdpbf16ps (16 x 16 float accumulators, 16 x 32 bf16 operands), the online
// softmax and the output's rescaling in vectors. Four accumulator tiles cover 32 queries x 32
// keys (scores) or 32 queries x 32 dims (output); the other four hold two operand tiles of
// each side. k and v are packed once per (batch, head) into the pair-interleaved layout that
// tdpbf16ps reads as its second operand; keys and dims are zero-padded to whole tiles.
//
// The including file defines the tile operations as macros (GCC's tile intrinsics are macros
// that paste the tile's number into the instruction's text, so the numbers stay literals):
//   II_TILE_CONFIGURE()  every tile 16 rows of 64 bytes      II_TILE_RELEASE()
//   II_TILE_ZERO(t)  II_TILE_LOAD(t, pointer, stride in bytes)  II_TILE_STORE(t, pointer, stride)
//   II_TILE_DOT(c, a, b)  c += a · b as tdpbf16ps (a: 16 rows of 16 bf16 pairs; b: 16 rows of
//                         16 pairs, row k holding element pair k of each of 16 columns)
// and instantiates run_amx_attention over Rows: a float vector of common/simd_float.h (W, F,
// arithmetic, exp2) with store_in(uint16_t*, F) and to_in(float), W floats or one to bf16
// rounded to nearest even (isa.h's Avx512Bf16).
//
// Everything is in an anonymous namespace: every including file gets its own copy, compiled
// for its instruction set (see kernels.h).
#include <cstdint>
#include <cstdlib>

#include "model/cpu/isa.h"
#include "model/cpu/kernels.h"

#if !defined(II_TILE_CONFIGURE) || !defined(II_TILE_RELEASE) || !defined(II_TILE_ZERO) || !defined(II_TILE_LOAD) || \
    !defined(II_TILE_STORE) || !defined(II_TILE_DOT)
#error "define the II_TILE_ operations before including attention_amx_impl.h"
#endif

namespace ii::cpu_kernels {
namespace amx_detail {
namespace {

constexpr int64_t kTileRows = 16;  // rows of every tile
constexpr int64_t kTileBf16 = 32;  // bf16 elements in a tile row (64 bytes)
constexpr int64_t kGroup = 32;     // queries, keys or dims per 2 x 2 block of accumulators
constexpr int64_t kKeyBlock = 512;  // keys whose packed k and v stay in cache while a task passes
constexpr int64_t kTaskRows = 64;   // queries per task
constexpr int64_t kMaxDim = round_up(kMaxHeadDim, kGroup);

template <class Rows>
class AmxAttention {
  using V = Rows;
  using F = typename Rows::F;

 public:
  explicit AmxAttention(const AttentionProblem& problem)
      : pr_(problem),
        dim_(round_up(problem.head_dim, kGroup)),
        keys_padded_(round_up(problem.keys, kGroup)),
        tasks_per_slice_((problem.queries + kTaskRows - 1) / kTaskRows),
        scale_log2e_(problem.scale * 1.44269504088896341f) {
    const int64_t elements = pr_.batch * pr_.heads * keys_padded_ * dim_;
    packed_k_ = aligned_elements<uint16_t>(elements);
    packed_v_ = aligned_elements<uint16_t>(elements);
  }
  ~AmxAttention() {
    std::free(packed_k_);
    std::free(packed_v_);
  }
  AmxAttention(const AmxAttention&) = delete;
  AmxAttention& operator=(const AmxAttention&) = delete;

  bool run(ParallelFor parallel) {
    if (!packed_k_ || !packed_v_) return false;
    const int64_t slices = pr_.batch * pr_.heads;
    parallel(slices, [](void* self, int64_t slice) { static_cast<AmxAttention*>(self)->pack(slice); }, this);
    parallel(slices * tasks_per_slice_,
             [](void* self, int64_t task) { static_cast<AmxAttention*>(self)->run_task(task); }, this);
    return true;
  }

 private:
  // k as panels of 16 keys, [panel][dim pair][key][2]: 16 dim pairs of a panel are the second
  // operand of q·kᵀ. v as [key pair][dim][2]: 16 key pairs x 16 dims are that of p·v.
  void pack(int64_t slice) {
    const int64_t b = slice / pr_.heads, h = slice % pr_.heads, d = pr_.head_dim;
    const uint16_t* k = slice_at(static_cast<const uint16_t*>(pr_.k), pr_.k_strides, b, h);
    const uint16_t* v = slice_at(static_cast<const uint16_t*>(pr_.v), pr_.v_strides, b, h);
    uint16_t* pk = packed_k_ + slice * keys_padded_ * dim_;
    uint16_t* pv = packed_v_ + slice * keys_padded_ * dim_;
    for (int64_t n = 0; n < keys_padded_; ++n) {
      const bool key = n < pr_.keys;
      const uint16_t* krow = key ? k + n * pr_.k_strides[2] : nullptr;
      const uint16_t* vrow = key ? v + n * pr_.v_strides[2] : nullptr;
      uint16_t* kpanel = pk + (n / kTileRows) * dim_ * kTileRows + (n % kTileRows) * 2;
      uint16_t* vpair = pv + (n / 2) * dim_ * 2 + n % 2;
      for (int64_t x = 0; x < dim_; ++x) {
        const bool real = key && x < d;
        kpanel[(x / 2) * kTileBf16 + x % 2] = real ? krow[x] : uint16_t(0);
        vpair[x * 2] = real ? vrow[x] : uint16_t(0);
      }
    }
  }

  // scores[32][32 keys at j] = q[32 rows] · k[keys j..j+32) for every group of 32 keys.
  void score_block(const uint16_t* q, const uint16_t* pk, int64_t columns, float* scores) const {
    const int64_t q_stride = dim_ * 2, s_stride = kKeyBlock * 4, panel = dim_ * kTileRows;
    for (int64_t j = 0; j < columns; j += kGroup) {
      II_TILE_ZERO(0);
      II_TILE_ZERO(1);
      II_TILE_ZERO(2);
      II_TILE_ZERO(3);
      const uint16_t* k0 = pk + (j / kTileRows) * panel;
      for (int64_t t = 0; t < dim_; t += kTileBf16) {
        II_TILE_LOAD(4, q + t, q_stride);
        II_TILE_LOAD(5, q + kTileRows * dim_ + t, q_stride);
        II_TILE_LOAD(6, k0 + t * kTileRows, 64);
        II_TILE_LOAD(7, k0 + panel + t * kTileRows, 64);
        II_TILE_DOT(0, 4, 6);
        II_TILE_DOT(1, 4, 7);
        II_TILE_DOT(2, 5, 6);
        II_TILE_DOT(3, 5, 7);
      }
      II_TILE_STORE(0, scores + j, s_stride);
      II_TILE_STORE(1, scores + j + kTileRows, s_stride);
      II_TILE_STORE(2, scores + kTileRows * kKeyBlock + j, s_stride);
      II_TILE_STORE(3, scores + kTileRows * kKeyBlock + j + kTileRows, s_stride);
    }
  }

  // out[32 rows][dims] += probs[32 rows][columns keys] · v.
  void value_block(const uint16_t* probs, const uint16_t* pv, int64_t columns, float* out) const {
    const int64_t o_stride = dim_ * 4, p_stride = kKeyBlock * 2, v_stride = dim_ * 4;
    float* lower = out + kTileRows * dim_;
    for (int64_t c = 0; c < dim_; c += kGroup) {
      II_TILE_LOAD(0, out + c, o_stride);
      II_TILE_LOAD(1, out + c + kTileRows, o_stride);
      II_TILE_LOAD(2, lower + c, o_stride);
      II_TILE_LOAD(3, lower + c + kTileRows, o_stride);
      for (int64_t u = 0; u < columns; u += kTileBf16) {
        const uint16_t* v0 = pv + (u / 2) * dim_ * 2 + c * 2;
        II_TILE_LOAD(4, probs + u, p_stride);
        II_TILE_LOAD(5, probs + kTileRows * kKeyBlock + u, p_stride);
        II_TILE_LOAD(6, v0, v_stride);
        II_TILE_LOAD(7, v0 + kTileRows * 2, v_stride);
        II_TILE_DOT(0, 4, 6);
        II_TILE_DOT(1, 4, 7);
        II_TILE_DOT(2, 5, 6);
        II_TILE_DOT(3, 5, 7);
      }
      II_TILE_STORE(0, out + c, o_stride);
      II_TILE_STORE(1, out + c + kTileRows, o_stride);
      II_TILE_STORE(2, lower + c, o_stride);
      II_TILE_STORE(3, lower + c + kTileRows, o_stride);
    }
  }

  // The online softmax of one row of scores (`valid` real keys of `columns`): updates the
  // running maximum (log2 units of the scaled scores) and sum, writes the probabilities as bf16
  // and rescales the row's output so far.
  void softmax_row(float* scores, int64_t valid, int64_t columns, uint16_t* probs, float* out, float& max,
                   float& sum) const {
    for (int64_t j = valid; j < columns; ++j) scores[j] = -__builtin_inff();
    F vmax = V::set1(-__builtin_inff());
    for (int64_t j = 0; j < columns; j += V::W) vmax = V::max(vmax, V::load(scores + j));
    const float row_max = V::hmax(vmax) * scale_log2e_;
    const float new_max = row_max > max ? row_max : max;
    const float alpha = __builtin_exp2f(max - new_max);
    const F c = V::set1(scale_log2e_), m = V::set1(new_max);
    F vsum = V::zero();
    for (int64_t j = 0; j < columns; j += V::W) {
      const F p = V::template exp2<4>(V::fmsub(V::load(scores + j), c, m));
      vsum = V::add(vsum, p);
      Rows::store_in(probs + j, p);
    }
    sum = sum * alpha + V::hsum(vsum);
    max = new_max;
    if (alpha != 1.0f) {
      const F a = V::set1(alpha);
      for (int64_t x = 0; x < dim_; x += V::W) V::store(out + x, V::mul(V::load(out + x), a));
    }
  }

  void run_task(int64_t task) {
    const int64_t slice = task / tasks_per_slice_, first = (task % tasks_per_slice_) * kTaskRows;
    const int64_t b = slice / pr_.heads, h = slice % pr_.heads, d = pr_.head_dim;
    const int64_t rows = smaller(kTaskRows, pr_.queries - first), rows_padded = round_up(rows, kGroup);

    // On the stack (about 150 KB): every thread here is a std::thread or the caller's, with
    // megabytes of stack.
    alignas(64) uint16_t q[kTaskRows * kMaxDim];
    alignas(64) float out[kTaskRows * kMaxDim];
    alignas(64) float scores[kGroup * kKeyBlock];
    alignas(64) uint16_t probs[kGroup * kKeyBlock];
    float max[kTaskRows], sum[kTaskRows];

    const uint16_t* qsrc =
        slice_at(static_cast<const uint16_t*>(pr_.q), pr_.q_strides, b, h) + first * pr_.q_strides[2];
    for (int64_t r = 0; r < rows_padded; ++r) {
      for (int64_t x = 0; x < dim_; ++x) q[r * dim_ + x] = r < rows && x < d ? qsrc[r * pr_.q_strides[2] + x] : 0;
      for (int64_t x = 0; x < dim_; ++x) out[r * dim_ + x] = 0.0f;
      max[r] = -__builtin_inff();
      sum[r] = 0.0f;
    }

    II_TILE_CONFIGURE();
    const uint16_t* pk = packed_k_ + slice * keys_padded_ * dim_;
    const uint16_t* pv = packed_v_ + slice * keys_padded_ * dim_;
    for (int64_t k0 = 0; k0 < pr_.keys; k0 += kKeyBlock) {
      const int64_t valid = smaller(kKeyBlock, pr_.keys - k0), columns = round_up(valid, kGroup);
      for (int64_t g = 0; g < rows_padded; g += kGroup) {
        score_block(q + g * dim_, pk + k0 * dim_, columns, scores);
        for (int64_t r = 0; r < kGroup; ++r)
          softmax_row(scores + r * kKeyBlock, valid, columns, probs + r * kKeyBlock, out + (g + r) * dim_,
                      max[g + r], sum[g + r]);
        value_block(probs, pv + k0 * dim_, columns, out + g * dim_);
      }
    }
    II_TILE_RELEASE();

    uint16_t* dst = slice_at(static_cast<uint16_t*>(pr_.out), pr_.out_strides, b, h) + first * pr_.out_strides[2];
    for (int64_t r = 0; r < rows; ++r) {
      const float inv = 1.0f / sum[r];
      for (int64_t x = 0; x < d; ++x) dst[r * pr_.out_strides[2] + x] = Rows::to_in(out[r * dim_ + x] * inv);
    }
  }

  const AttentionProblem& pr_;
  const int64_t dim_, keys_padded_, tasks_per_slice_;
  const float scale_log2e_;
  uint16_t* packed_k_ = nullptr;
  uint16_t* packed_v_ = nullptr;
};

}  // namespace
}  // namespace amx_detail

namespace {

template <class Rows>
bool run_amx_attention(const AttentionProblem& problem, ParallelFor parallel) {
  amx_detail::AmxAttention<Rows> attention(problem);
  return attention.run(parallel);
}

}  // namespace
}  // namespace ii::cpu_kernels
