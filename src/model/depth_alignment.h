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

}  // namespace ii
