#pragma once
// The network's depth put where the scene is: each context view's predicted depth moved about
// its camera onto the scene's own 3D points (a capture's COLMAP points, points triangulated from
// its photos, a synthetic scene's depth maps) that the view sees outside its mask. First one scale
// per view, the median ratio; then, with `detail`, a correction that varies over the picture: the
// points' remaining log ratios spread over their neighbourhood. A small model's depth is wrong in
// scale and in shape: in make demo's room the default model's is 1.4x too far and draws the table
// at the floor's depth, which one scale cannot mend. The Gaussians' positions and sizes follow the
// depth, so every view still sees its own Gaussians where it saw them.
#include <string>
#include <vector>

#include <Eigen/Core>

#include "gaussians/gaussians.h"
#include "geometry/options.h"
#include "model/scene_input.h"

namespace ii {

struct DepthAlignment {
  std::string view;
  double scale = 1.0;      // the view's factor (1: too few points)
  int64_t points = 0;      // the points that decided it
  double detail_mean = 0;  // mean |log| of the correction beyond the scale over the picture (0: none)
};

// Scales `maps` (the network's output for `input`, pose-normalised frame) in place; `points` in
// the scene's frame. A view that sees fewer than `min_points` of them keeps its depth.
// options.detail = 0: one scale per view.
std::vector<DepthAlignment> align_depth_to_points(GaussianMaps& maps, const SceneInput& input,
                                                  const std::vector<Eigen::Vector3d>& points,
                                                  const DepthDetailOptions& options = {}, int64_t min_points = 20);

// One factor that brings `predicted` depth (H, W) to `measured` (H, W, the same units once scaled):
// the median ratio over the first of `where` (each (H, W) bool, in order of preference) that holds
// at least `min_pixels` pixels; 1 when none does. Fill scales the network's depth of a hole to
// the rendered scene's around it this way.
double median_depth_ratio(const torch::Tensor& measured, const torch::Tensor& predicted,
                          const std::vector<torch::Tensor>& where, int64_t min_pixels = 16);

}  // namespace ii
