#pragma once
// The fused attention loop that the instruction-set files (kernels_*.cpp) instantiate over the
// traits of isa.h, flash-attention form.
//
// For each task (batch, head, tile of queries) and each key block: scores for kScoreRows
// queries at a time into a small float buffer, the online softmax (running maximum and sum;
// the output rescaled when the maximum grows), probabilities stored in the input type, then
// output += probabilities · v. Scores never leave the cache. k and v are first packed per
// (batch, head) into the layouts the microkernels read as whole vectors, zero-padded
// to whole key groups and vectors; padded keys get a score of -inf.
//
#include <cstdint>
#include <cstdlib>

#include "model/cpu/isa.h"
#include "model/cpu/kernels.h"

namespace ii::cpu_kernels {
namespace {

template <class Isa>
class Attention {
 public:
  using In = typename Isa::In;
  using F = typename Isa::F;
  using X = typename Isa::X;
  static constexpr int W = Isa::W, P = Isa::kPair;
  static constexpr int SR = Isa::kScoreRows, SV = Isa::kScoreVectors;
  static constexpr int VR = Isa::kValueRows, VV = Isa::kValueVectors;
  static constexpr int64_t kGroup = int64_t{W} * SV;  // keys per score microkernel call
  static constexpr int64_t kBlock = Isa::kKeyBlock;
  static constexpr int64_t kTile = Isa::kTileRows;
  static constexpr int64_t kMaxDp = round_up(kMaxHeadDim, P);
  static constexpr int64_t kMaxDv = round_up(kMaxHeadDim, W);
  static_assert(kBlock % kGroup == 0 && kTile % SR == 0 && SR % VR == 0, "tile shapes");

  explicit Attention(const AttentionProblem& problem)
      : pr_(problem),
        steps_((problem.head_dim + P - 1) / P),
        dp_(steps_ * P),
        dv_(round_up(problem.head_dim, W)),
        keys_padded_(round_up(problem.keys, kGroup)),
        tiles_((problem.queries + kTile - 1) / kTile),
        scale_log2e_(problem.scale * 1.44269504088896341f) {
    const int64_t slices = pr_.batch * pr_.heads;
    packed_k_ = aligned_elements<In>(slices * keys_padded_ * dp_);
    packed_v_ = aligned_elements<In>(slices * keys_padded_ * dv_);
  }
  ~Attention() {
    std::free(packed_k_);
    std::free(packed_v_);
  }
  Attention(const Attention&) = delete;
  Attention& operator=(const Attention&) = delete;

  bool run(ParallelFor parallel) {
    if (!packed_k_ || !packed_v_) return false;
    const int64_t slices = pr_.batch * pr_.heads;
    parallel(slices, [](void* self, int64_t slice) { static_cast<Attention*>(self)->pack(slice); }, this);
    parallel(slices * tiles_, [](void* self, int64_t task) { static_cast<Attention*>(self)->run_tile(task); },
             this);
    return true;
  }

 private:
  // k into panels of W keys, [panel][step][key][pair]: the score microkernel loads one step of
  // W keys as one vector. v into [key pair][dim][pair]: the value microkernel loads W dims of
  // two consecutive keys as one vector.
  void pack(int64_t slice) {
    const int64_t b = slice / pr_.heads, h = slice % pr_.heads, d = pr_.head_dim;
    const In* k = slice_at(static_cast<const In*>(pr_.k), pr_.k_strides, b, h);
    const In* v = slice_at(static_cast<const In*>(pr_.v), pr_.v_strides, b, h);
    In* pk = packed_k_ + slice * keys_padded_ * dp_;
    In* pv = packed_v_ + slice * keys_padded_ * dv_;
    for (int64_t n = 0; n < keys_padded_; ++n) {
      const bool key = n < pr_.keys;
      const In* krow = key ? k + n * pr_.k_strides[2] : nullptr;
      In* panel = pk + (n / W) * dp_ * W + (n % W) * P;
      for (int64_t s = 0; s < steps_; ++s)
        for (int e = 0; e < P; ++e) {
          const int64_t x = s * P + e;
          panel[s * W * P + e] = key && x < d ? krow[x] : In(0);
        }
      const In* vrow = key ? v + n * pr_.v_strides[2] : nullptr;
      In* pair = pv + (n / P) * dv_ * P + n % P;
      for (int64_t x = 0; x < dv_; ++x) pair[x * P] = key && x < d ? vrow[x] : In(0);
    }
  }

  // scores[r][j] = q[r] · k[j] for kScoreRows queries and one group of kGroup keys.
  void score_group(const In* q, const In* panels, float* scores) const {
    F acc[SR][SV];
#pragma GCC unroll 16
    for (int r = 0; r < SR; ++r)
#pragma GCC unroll 4
      for (int c = 0; c < SV; ++c) acc[r][c] = Isa::zero();
    const int64_t panel_size = dp_ * W;
    for (int64_t s = 0; s < steps_; ++s) {
      X kv[SV];
#pragma GCC unroll 4
      for (int c = 0; c < SV; ++c) kv[c] = Isa::load_in(panels + c * panel_size + s * W * P);
#pragma GCC unroll 16
      for (int r = 0; r < SR; ++r) {
        const X qv = Isa::broadcast_in(q + r * dp_ + s * P);
#pragma GCC unroll 4
        for (int c = 0; c < SV; ++c) acc[r][c] = Isa::madd(acc[r][c], qv, kv[c]);
      }
    }
#pragma GCC unroll 16
    for (int r = 0; r < SR; ++r)
#pragma GCC unroll 4
      for (int c = 0; c < SV; ++c) Isa::store(scores + r * kBlock + c * W, acc[r][c]);
  }

  // out[r][0, NV*W) = out[r] * alpha[r] + Σ_t probs[r][t] v[t] for kValueRows queries.
  template <int NV>
  void value_chunk(const In* probs, const In* v, int64_t pairs, float* out, const float* alpha) const {
    F acc[VR][NV];
#pragma GCC unroll 8
    for (int r = 0; r < VR; ++r) {
      const F a = Isa::set1(alpha[r]);
#pragma GCC unroll 4
      for (int c = 0; c < NV; ++c) acc[r][c] = Isa::mul(Isa::load(out + r * dv_ + c * W), a);
    }
    const int64_t v_step = dv_ * P;
    for (int64_t t = 0; t < pairs; ++t, v += v_step, probs += P) {
      X vv[NV];
#pragma GCC unroll 4
      for (int c = 0; c < NV; ++c) vv[c] = Isa::load_in(v + c * W * P);
#pragma GCC unroll 8
      for (int r = 0; r < VR; ++r) {
        const X pr = Isa::broadcast_in(probs + r * kBlock);
#pragma GCC unroll 4
        for (int c = 0; c < NV; ++c) acc[r][c] = Isa::madd(acc[r][c], pr, vv[c]);
      }
    }
#pragma GCC unroll 8
    for (int r = 0; r < VR; ++r)
#pragma GCC unroll 4
      for (int c = 0; c < NV; ++c) Isa::store(out + r * dv_ + c * W, acc[r][c]);
  }

  void value_rows(const In* probs, const In* v, int64_t pairs, float* out, const float* alpha) const {
    for (int64_t x = 0; x < dv_; x += VV * W) {
      const int64_t vectors = smaller(VV, (dv_ - x) / W);
      const In* vx = v + x * P;
      float* ox = out + x;
      if (vectors == VV) value_chunk<VV>(probs, vx, pairs, ox, alpha);
      else if (vectors == 3) value_chunk<(VV > 3 ? 3 : VV)>(probs, vx, pairs, ox, alpha);
      else if (vectors == 2) value_chunk<(VV > 2 ? 2 : VV)>(probs, vx, pairs, ox, alpha);
      else value_chunk<1>(probs, vx, pairs, ox, alpha);
    }
  }

  // Online softmax of one row of scores (`valid` real keys of `columns`): updates the running
  // maximum (in log2 units of the scaled scores) and sum, writes the probabilities in the
  // input type and returns the factor that rescales the row's earlier output.
  float softmax_row(float* scores, int64_t valid, int64_t columns, In* probs, float& max, float& sum) const {
    for (int64_t j = valid; j < columns; ++j) scores[j] = -__builtin_inff();
    F vmax = Isa::set1(-__builtin_inff());
    for (int64_t j = 0; j < columns; j += W) vmax = Isa::max(vmax, Isa::load(scores + j));
    const float new_max = larger(max, Isa::hmax(vmax) * scale_log2e_);
    const float alpha = __builtin_exp2f(max - new_max);
    const F c = Isa::set1(scale_log2e_), m = Isa::set1(new_max);
    F vsum = Isa::zero();
    for (int64_t j = 0; j < columns; j += W) {
      const F p = Isa::template exp2<Isa::kExpDegree>(Isa::fmsub(Isa::load(scores + j), c, m));
      vsum = Isa::add(vsum, p);
      Isa::store_in(probs + j, p);
    }
    sum = sum * alpha + Isa::hsum(vsum);
    max = new_max;
    return alpha;
  }

  void run_tile(int64_t task) {
    const int64_t slice = task / tiles_, tile = task % tiles_;
    const int64_t b = slice / pr_.heads, h = slice % pr_.heads, d = pr_.head_dim;
    const int64_t first = tile * kTile, rows = smaller(kTile, pr_.queries - first);
    const int64_t rows_padded = round_up(rows, SR);

    // On the stack (about 110 KB for bf16, 150 KB for float): every thread here is a std::thread
    // or the caller's, with megabytes of stack.
    alignas(64) In q[kTile * kMaxDp];
    alignas(64) float out[kTile * kMaxDv];
    alignas(64) float scores[SR * kBlock];
    alignas(64) In probs[SR * kBlock];
    float max[kTile], sum[kTile], alpha[SR];

    const In* qsrc = slice_at(static_cast<const In*>(pr_.q), pr_.q_strides, b, h) + first * pr_.q_strides[2];
    for (int64_t r = 0; r < rows_padded; ++r) {
      for (int64_t x = 0; x < dp_; ++x) q[r * dp_ + x] = r < rows && x < d ? qsrc[r * pr_.q_strides[2] + x] : In(0);
      for (int64_t x = 0; x < dv_; ++x) out[r * dv_ + x] = 0.0f;
      max[r] = -__builtin_inff();
      sum[r] = 0.0f;
    }

    const In* pk = packed_k_ + slice * keys_padded_ * dp_;
    const In* pv = packed_v_ + slice * keys_padded_ * dv_;
    for (int64_t k0 = 0; k0 < pr_.keys; k0 += kBlock) {
      const int64_t valid = smaller(kBlock, pr_.keys - k0), columns = round_up(valid, kGroup);
      for (int64_t g = 0; g < rows_padded; g += SR) {
        for (int64_t j = 0; j < columns; j += kGroup) score_group(q + g * dp_, pk + (k0 + j) * dp_, scores + j);
        for (int r = 0; r < SR; ++r)
          alpha[r] = softmax_row(scores + r * kBlock, valid, columns, probs + r * kBlock, max[g + r], sum[g + r]);
        for (int r = 0; r < SR; r += VR)
          value_rows(probs + r * kBlock, pv + k0 * dv_, columns / P, out + (g + r) * dv_, alpha + r);
      }
    }

    In* dst = slice_at(static_cast<In*>(pr_.out), pr_.out_strides, b, h) + first * pr_.out_strides[2];
    for (int64_t r = 0; r < rows; ++r) {
      const float inv = 1.0f / sum[r];
      for (int64_t x = 0; x < d; ++x) dst[r * pr_.out_strides[2] + x] = Isa::to_in(out[r * dv_ + x] * inv);
    }
  }

  const AttentionProblem& pr_;
  const int64_t steps_, dp_, dv_, keys_padded_, tiles_;
  const float scale_log2e_;
  In* packed_k_ = nullptr;
  In* packed_v_ = nullptr;
};

template <class Isa>
bool run_attention(const AttentionProblem& problem, ParallelFor parallel) {
  Attention<Isa> attention(problem);
  return attention.run(parallel);
}

}  // namespace
}  // namespace ii::cpu_kernels
