#pragma once
// Pieces of render() shared by the back ends and the reference renderer. Internal.
#include "render/cpu/cpu_rasterizer.h"
#include "render/rasterizer.h"

namespace ii::render_detail {

// Validated camera (throws ii::Error naming the problem).
splat::CameraParams camera_params(const RenderCamera& camera, const RenderOptions& options);

// Validated inputs: contiguous, of the dtype of means, opacities flattened to (N).
RasterInputs prepare_inputs(const GaussianSet& gaussians);

// CUDA back end (cuda_dispatch.cpp); throws when the build has no CUDA kernels.
RasterOutputs cuda_forward(const splat::CameraParams& cam, const RasterInputs& in, RasterState* state);
RasterGrads cuda_backward(const splat::CameraParams& cam, const RasterInputs& in, const RasterState& state,
                          const RasterOutputs& out, const torch::Tensor& grad_rgb, const torch::Tensor& grad_alpha,
                          const torch::Tensor& grad_depth);

}  // namespace ii::render_detail
