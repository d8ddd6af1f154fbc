#pragma once
// The network's input tensors for one scene, built exactly as the official inference does
// (spec §1.3): view 0 is the reference, its RGB replaced by the 2D-inpainted image and its
// mask channel zero; the other views are greyed out inside their object mask (0.0 in the
// [-1,1] range) with the mask as 4th channel; Plücker rays [d, o x d] in the normalised
// world frame.
#include <string>
#include <vector>

#include "common/torch.h"

#include "camera/camera.h"
#include "data/preprocess.h"

namespace ii {

struct ModelInput {
  torch::Tensor images;     // (V, 4, H, W) float32: RGB in [-1,1] masked, then mask
  torch::Tensor plucker;    // (V, 6, H, W) float32
  torch::Tensor cameras;    // (V, 20) official camera vectors
  torch::Tensor rays_o;     // (V, H, W, 3)
  torch::Tensor rays_d;     // (V, H, W, 3) unit directions
  torch::Tensor rays_d_un;  // (V, H, W, 3) z-depth directions
  std::vector<Camera> view_cameras;  // normalised cameras of the views
  std::vector<std::string> names;
};

// `views[0]` is the reference; its rgb must already be the inpainted image. Cameras are
// normalised with `normalization` (fit it over the scene's cameras, spec §5.1).
ModelInput build_model_input(const std::vector<PreparedView>& views,
                             const PoseNormalization& normalization);

// Tensor views of the per-view ray data (V, H, W, 3) for a set of cameras. The last two sets
// are kept (a server's edit predicts twice with the same cameras: 35 ms each at 512 high on an
// H100 machine's CPU): the tensors returned may be shared, never write into them.
void compute_ray_tensors(const std::vector<Camera>& cameras, torch::Tensor& rays_o,
                         torch::Tensor& rays_d, torch::Tensor& rays_d_un, torch::Tensor& plucker);

}  // namespace ii
