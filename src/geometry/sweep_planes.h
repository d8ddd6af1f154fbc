#pragma once
// The per-depth loop of sweep_correlation (geometry/sweep_correlation.h) on plain arrays: for each
// depth, every reference pixel's point projected into the source, the source sampled there, the
// window sums and the correlation, in one pass that the compiler vectorises. Compiled twice, for
// the baseline instruction set (sweep_planes.cpp) and for AVX2 + FMA, whose gathers sample eight
// pixels at once (sweep_planes_avx2.cpp, called only where the CPU has them). Torch-free.
#include <cstdint>

namespace ii::sweep_detail {

struct SweepIo {
  int64_t height, width;                 // the reference's picture
  int64_t source_height, source_width;   // the source's, without its border
  const float* bordered_source;          // (source_height + 2, source_width + 2): one zero pixel around
  const float* reference;                // (height * width) grey levels
  const float* reference_mean;           // their window means
  const float* reference_deviation;      // their window standard deviations
  const float* inverse_count;            // 1 / each window's pixels inside the picture
  const float* ray;                      // (3, height * width): each pixel's ray, turned into the source's frame
  float translation[3];                  // the reference's centre in the source's frame
  float fx, fy, cx, cy;                  // the source's intrinsics, cx and cy less half a pixel
  const float* depths;                   // (planes, height * width)
  int half;                              // the window's half side
  float* correlation;                    // (planes, height * width) out
};

// Sums of `planes` consecutive (h, w) pictures over squares of `half` pixels each side, zero
// outside the picture: down the columns into `down`, then along the rows into `out`.
void window_sums(const float* in, float* down, float* out, int planes, int64_t h, int64_t w, int half);
// Scratch for one thread: 10 * height * width floats.
int64_t sweep_scratch_floats(const SweepIo& io);
// Depths [first, last).
void sweep_planes(const SweepIo& io, int64_t first, int64_t last, float* scratch);
void sweep_planes_avx2(const SweepIo& io, int64_t first, int64_t last, float* scratch);

}  // namespace ii::sweep_detail
