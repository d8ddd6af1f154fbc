#pragma once
// One tile's compositing and its backward pass for float splats, vectorised over the pixels
// of a tile row (8 at a time) in raster_tiles_avx2.cpp: compiled for AVX2 + FMA and called only
// where the CPU has them (common/cpu_features.h). cpu_rasterizer.cpp keeps the scalar form, for
// other CPUs and for double. The AVX2 file includes nothing but this header (plain structs),
// the float vectors and C headers: an inline function of a shared header compiled there could
// be the copy the linker keeps for every other caller (see model/cpu/kernels.h).
#include <cstdint>

#include "render/splat_math.h"

namespace ii::render_detail {

// A tile's pixels [x0, x1) x [y0, y1) and its range [start, end) of the tile lists.
struct TileBounds {
  int x0, y0, x1, y1;
  int64_t start, end;
};

// What every tile of one render reads, and the images it writes (H x W, rgb interleaved).
struct TileForwardIo {
  const splat::Splat2D<float>* splats;
  const splat::PixelBox* boxes;
  const int32_t* tile_gaussians;
  int width;
  float background[3];
  float* rgb;
  float* alpha;
  float* depth;
  float* final_T;
  int32_t* last;  // last contributor, index within the tile's range, -1 none
};

// The backward pass's inputs (the forward pass's outputs and the gradients of the images,
// each of which may be null: zero) and, per (tile, Gaussian) entry, that tile's share of the
// Gaussian's 2D gradient.
struct TileBackwardIo {
  const splat::Splat2D<float>* splats;
  const splat::PixelBox* boxes;
  const int32_t* tile_gaussians;
  int width;
  float background[3];
  const float* alpha;
  const float* depth;
  const float* final_T;
  const int32_t* last;
  const float* grad_rgb;
  const float* grad_alpha;
  const float* grad_depth;
  splat::Splat2DGrad<float>* entry_grads;
};

void forward_tile_avx2(const TileForwardIo& io, const TileBounds& tile);
void backward_tile_avx2(const TileBackwardIo& io, const TileBounds& tile);

}  // namespace ii::render_detail
