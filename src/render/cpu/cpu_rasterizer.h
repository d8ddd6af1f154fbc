#pragma once
// CPU back end of render(): projection, depth sort, tile binning, per-tile compositing and
// its analytic backward, for float or double tensors. Internal to src/render.
#include "common/torch.h"

#include "render/splat_math.h"

namespace ii::render_detail {

// The validated inputs of one render: contiguous tensors of one floating dtype.
struct RasterInputs {
  torch::Tensor means, quats, scales, opacities, colors;  // (N,3) (N,4) (N,3) (N) (N,3)|(N,K,3)
  int sh_degree = -1;  // -1: colors are RGB
  int num_coeffs = 0;  // K when SH (coefficients per channel stored), else 0
};

// What the forward pass keeps for the backward pass; tensors, so that it can live on an
// autograd context.
struct RasterState {
  torch::Tensor splats;          // (N, 11) scalar: Splat2D (mx my A B C depth opacity level r g b)
  torch::Tensor boxes;           // (N, 4) int32: PixelBox, empty for culled Gaussians
  torch::Tensor tile_offsets;    // (tiles + 1) int64: each tile's range in tile_gaussians
  torch::Tensor tile_gaussians;  // (M) int32: per tile, Gaussian ids front to back
  torch::Tensor last;            // (H, W) int32: last contributor, index within the tile's range, -1 none
  torch::Tensor final_T;         // (H, W) scalar: transmittance left after compositing
};

struct RasterOutputs {
  torch::Tensor rgb, alpha, depth;  // (H,W,3) (H,W,1) (H,W,1)
};

struct RasterGrads {
  torch::Tensor means, quats, scales, opacities, colors;  // shaped like the inputs
};

RasterOutputs cpu_forward(const splat::CameraParams& cam, const RasterInputs& in, RasterState* state);

// grad_* may be undefined (zero). `out` is what cpu_forward returned.
RasterGrads cpu_backward(const splat::CameraParams& cam, const RasterInputs& in, const RasterState& state,
                         const RasterOutputs& out, const torch::Tensor& grad_rgb, const torch::Tensor& grad_alpha,
                         const torch::Tensor& grad_depth);

}  // namespace ii::render_detail
