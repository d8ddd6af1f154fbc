#pragma once
// A camera's rigid transform and pinhole projection on tensors of points (OpenCV axes, pixel
// centres at +0.5, as render() draws them): for the renderer's culling, fill and refinement, and
// for the model's check of one view's Gaussians against another view (geometry/floaters.h).
#include <utility>

#include "common/torch.h"

#include "camera/camera.h"

namespace ii {

// The rotation (3, 3) and translation (3) of a 4 x 4 rigid transform, as tensors of `options`.
std::pair<torch::Tensor, torch::Tensor> rotation_and_translation(const Eigen::Matrix4d& m,
                                                                 const torch::TensorOptions& options);

// Points (N, 3) moved by a 4 x 4 rigid transform, on the points' device and in their type.
torch::Tensor transformed(const Eigen::Matrix4d& m, const torch::Tensor& points);

// Where world points (N, 3) land in a camera's image: their camera z, whether they are in front
// of it and inside the image, and the flat index of their pixel (clamped to the image).
struct PixelHit {
  torch::Tensor z, inside, index;
};
PixelHit project(const Camera& camera, const torch::Tensor& points);

}  // namespace ii
