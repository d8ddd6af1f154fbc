// sweep_planes for the baseline instruction set; sweep_planes_avx2.cpp is the same body for AVX2.
#include "geometry/sweep_planes_body.h"

namespace ii::sweep_detail {

void window_sums(const float* in, float* down, float* out, int planes, int64_t h, int64_t w, int half) {
  sum_windows(in, down, out, planes, h, w, half);
}

int64_t sweep_scratch_floats(const SweepIo& io) { return 10 * io.height * io.width; }

void sweep_planes(const SweepIo& io, int64_t first, int64_t last, float* scratch) {
  sweep_planes_body(io, first, last, scratch, warp);
}

}  // namespace ii::sweep_detail
