#pragma once
// The network's depth put where the scene is: each context view's predicted depth scaled about
// its camera so that it meets the scene's own 3D points (a capture's COLMAP points, a synthetic
// scene's depth maps) that the view sees outside its mask, by the median ratio. A small model's
// depth is more often right in shape than in scale (the default model's is about twice too far
// in make demo's room); the Gaussians' positions and sizes follow the depth, so every view still
// sees its own Gaussians where it saw them.
#include <string>
#include <vector>

#include <Eigen/Core>

#include "gaussians/gaussians.h"
#include "model/scene_input.h"

namespace ii {

struct DepthAlignment {
  std::string view;
  double scale = 1.0;  // the factor applied (1: too few points)
  int64_t points = 0;  // the points that decided it
};

// Scales `maps` (the network's output for `input`, pose-normalised frame) in place; `points` in
// the scene's frame. A view that sees fewer than `min_points` of them keeps its depth.
std::vector<DepthAlignment> align_depth_to_points(GaussianMaps& maps, const SceneInput& input,
                                                  const std::vector<Eigen::Vector3d>& points, int64_t min_points = 20);

// The same alignment in training, where a sample's depth target is known per pixel (depth maps,
// or sparse points triangulated from the photos, 0 where unknown): per view, the median of
// target / predicted over the pixels where both are positive, 1 where fewer than `min_points`.
// `predicted` and `target` are (V, 1, H, W); the factors (V) come without autograd history.
torch::Tensor median_depth_ratios(const torch::Tensor& predicted, const torch::Tensor& target, int64_t min_points = 20);

// `maps` (1, V, C, H, W) with each view's positions, depths and sizes scaled by `factors` (V)
// about its camera centre `centres` (V, 3), out of place: differentiable in the maps.
GaussianMaps scaled_about_cameras(const GaussianMaps& maps, const torch::Tensor& factors, const torch::Tensor& centres);

}  // namespace ii
