// region_weights.h's softmax-weighted planes, eight ring pixels at a time: a first pass for the
// largest logit, a second for the exponentials (common/simd_float.h's 2^x, degree 5) and their
// sums. Compiled with -mavx2 -mfma.
#include "geometry/region_weights.h"

#include <immintrin.h>

#include "common/simd_float.h"

namespace ii::region_detail {
namespace {

using V = simd::Avx2Float;
constexpr float kLog2e = 1.44269504f;

}  // namespace

void weighted_planes_avx2(const RingWeightsIo& io, int64_t begin, int64_t end) {
  const int64_t m = io.m;
  const float* r[kFeatures];
  for (int k = 0; k < kFeatures; ++k) r[k] = io.ring + k * m;
  const float* p0 = io.planes;
  const float* p1 = io.planes + m;
  const float* p2 = io.planes + 2 * m;
  for (int64_t i = begin; i < end; ++i) {
    V::F a[kFeatures];
    for (int k = 0; k < kFeatures; ++k) a[k] = V::set1(2 * io.pixels[i * kFeatures + k]);
    auto logits = [&](int64_t j) {
      V::F l = V::sub(V::zero(), V::load(io.bias + j));
      for (int k = 0; k < kFeatures; ++k) l = V::fmadd(a[k], V::load(r[k] + j), l);
      return l;
    };
    V::F top = V::set1(-3.0e38f);
    for (int64_t j = 0; j < m; j += V::W) top = V::max(top, logits(j));
    const V::F shift = V::set1(V::hmax(top) * kLog2e);
    V::F sum = V::zero(), s0 = V::zero(), s1 = V::zero(), s2 = V::zero();
    for (int64_t j = 0; j < m; j += V::W) {
      const V::F e = V::exp2<5>(V::fmsub(logits(j), V::set1(kLog2e), shift));
      sum = V::add(sum, e);
      s0 = V::fmadd(e, V::load(p0 + j), s0);
      s1 = V::fmadd(e, V::load(p1 + j), s1);
      s2 = V::fmadd(e, V::load(p2 + j), s2);
    }
    const float total = V::hsum(sum);
    io.weighted[3 * i] = V::hsum(s0) / total;
    io.weighted[3 * i + 1] = V::hsum(s1) / total;
    io.weighted[3 * i + 2] = V::hsum(s2) / total;
  }
}

}  // namespace ii::region_detail
