// The body of sweep_planes (geometry/sweep_planes.h), included by the files that compile it for
// each instruction set. Every loop is branch-free over whole rows so that it vectorises. No C++
// library header and nothing outside this file's anonymous namespace: an inline function compiled
// for AVX2 could be the copy the linker keeps for every other caller (see model/cpu/kernels.h).
#include <stdint.h>

#include "geometry/sweep_planes.h"

namespace ii::sweep_detail {
namespace {

inline int64_t least(int64_t a, int64_t b) { return a < b ? a : b; }
inline int64_t most(int64_t a, int64_t b) { return a > b ? a : b; }
inline void zero(float* to, int64_t count) {
  for (int64_t i = 0; i < count; ++i) to[i] = 0.f;
}

// Sums of `planes` consecutive (h, w) pictures over a square of `half` pixels each side, zero
// outside the picture: down the columns into `down`, then along the rows into `out`.
inline void sum_windows(const float* in, float* down, float* out, int planes, int64_t h, int64_t w, int half) {
  for (int plane = 0; plane < planes; ++plane)
    for (int64_t y = 0; y < h; ++y) {
      float* to = down + (plane * h + y) * w;
      zero(to, w);
      for (int64_t k = most(0, y - half); k <= least(h - 1, y + half); ++k) {
        const float* from = in + (plane * h + k) * w;
        for (int64_t x = 0; x < w; ++x) to[x] += from[x];
      }
    }
  for (int64_t row = 0; row < planes * h; ++row) {
    const float* from = down + row * w;
    float* to = out + row * w;
    zero(to, w);
    for (int64_t shift = -half; shift <= half; ++shift) {
      const int64_t begin = most(0, -shift), end = least(w, w - shift);
      for (int64_t x = begin; x < end; ++x) to[x] += from[x + shift];
    }
  }
}

// The source sampled where each pixel's point at its depth lands (bilinear, zero outside), as
// (value, value^2, value x reference) in `warped`; `inside` 1 where the point is in front of the
// source camera and inside its picture, else 0. Pixels [begin, height * width).
inline void warp(const SweepIo& io, const float* __restrict depth, float* __restrict warped, float* __restrict inside,
                 int64_t begin) {
  const int64_t n = io.height * io.width;
  const int stride = static_cast<int>(io.source_width + 2);
  const float width = static_cast<float>(io.source_width), height = static_cast<float>(io.source_height);
  const float tx = io.translation[0], ty = io.translation[1], tz = io.translation[2];
  const float fx = io.fx, fy = io.fy, cx = io.cx, cy = io.cy;
  const float* __restrict rx = io.ray;
  const float* __restrict ry = io.ray + n;
  const float* __restrict rz = io.ray + 2 * n;
  const float* __restrict reference = io.reference;
  const float* __restrict source = io.bordered_source;
  for (int64_t p = begin; p < n; ++p) {
    const float z = depth[p] * rz[p] + tz;
    const float reciprocal = 1.f / (z > 1e-6f ? z : 1e-6f);
    const float u = (depth[p] * rx[p] + tx) * reciprocal * fx + cx;
    const float v = (depth[p] * ry[p] + ty) * reciprocal * fy + cy;
    const bool near = (u > -1.f) & (u < width) & (v > -1.f) & (v < height);
    // Above -1, truncation after adding 1 is the floor plus 1: the border's column and row.
    const float uu = near ? u + 1.f : 0.f, vv = near ? v + 1.f : 0.f;
    const int column = static_cast<int>(uu), row = static_cast<int>(vv);
    const float ax = uu - static_cast<float>(column), ay = vv - static_cast<float>(row);
    const int at = row * stride + column;
    const float top = (1 - ax) * source[at] + ax * source[at + 1];
    const float bottom = (1 - ax) * source[at + stride] + ax * source[at + stride + 1];
    const float value = near ? (1 - ay) * top + ay * bottom : 0.f;
    warped[p] = value;
    warped[n + p] = value * value;
    warped[2 * n + p] = value * reference[p];
    inside[p] = ((z > 1e-6f) & (u >= -0.5f) & (u <= width - 0.5f) & (v >= -0.5f) & (v <= height - 0.5f)) ? 1.f : 0.f;
  }
}

// Warp: warp's signature (the vectorised one ends with it for the last pixels).
template <typename Warp>
void sweep_planes_body(const SweepIo& io, int64_t first, int64_t last, float* scratch, Warp warp_pixels) {
  const int64_t n = io.height * io.width;
  float* warped = scratch;
  float* down = scratch + 3 * n;
  float* sums = scratch + 6 * n;
  float* inside = scratch + 9 * n;
  for (int64_t d = first; d < last; ++d) {
    warp_pixels(io, io.depths + d * n, warped, inside, 0);
    sum_windows(warped, down, sums, 3, io.height, io.width, io.half);
    float* to = io.correlation + d * n;
    for (int64_t p = 0; p < n; ++p) {
      const float mean = sums[p] * io.inverse_count[p];
      const float variance = sums[n + p] * io.inverse_count[p] - mean * mean;
      const float deviation = __builtin_sqrtf(variance > 0.f ? variance : 0.f);
      const float covariance = sums[2 * n + p] * io.inverse_count[p] - mean * io.reference_mean[p];
      const float ncc = covariance / (deviation * io.reference_deviation[p] + 1e-4f);
      to[p] = inside[p] > 0.f ? ncc : -1.f;
    }
  }
}

}  // namespace
}  // namespace ii::sweep_detail
