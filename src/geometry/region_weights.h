#pragma once
// The reference's region takes its depth from the ring around it (geometry/region_surface.h): for
// each region pixel a softmax over the ring pixels of 2 a.b - |b|^2 (a, b their features) and the
// ring's planes weighted by it. In LibTorch that is a (region x ring) matrix written and read five
// times: scene 1 at 512 rows, 30,417 x 2,757, 176 ms on 2 cores, all of it memory traffic. Here
// each region pixel makes two passes over the ring, which stays in the cache, eight ring pixels at
// a time (region_weights_avx2.cpp, compiled for AVX2 + FMA and called only where the CPU has them;
// other CPUs keep the LibTorch form). Plain structs only: see render/cpu/raster_tiles.h.
#include <cstdint>

namespace ii::region_detail {

constexpr int kFeatures = 5;  // x, y, r, g, b, each divided by its width

struct RingWeightsIo {
  const float* pixels;  // (n, kFeatures): each region pixel's features
  const float* ring;    // (kFeatures, m): the ring's features, one row per feature
  const float* bias;    // (m): |b|^2 of each ring pixel
  const float* planes;  // (3, m): each ring pixel's plane of inverse depth, (1, x, y) coefficients
  int64_t m;            // a multiple of 8 (padding: bias 1e30, planes 0)
  float* weighted;      // (n, 3): each region pixel's weighted plane
};

// Region pixels [begin, end).
void weighted_planes_avx2(const RingWeightsIo& io, int64_t begin, int64_t end);

}  // namespace ii::region_detail
