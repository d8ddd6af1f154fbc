#pragma once
// Pictures of what the renderer and the network produce, for people to look at: depth maps
// in INFERNO colours (near = bright).
#include "common/torch.h"

#include "io/image.h"

namespace ii {

// One depth map (H, W), its own minimum to maximum mapped to bright to dark.
Image depth_colours(const torch::Tensor& depth);

// Depth frames of a video over one range, fixed from the 2nd to 98th percentile of the first
// frame that shows something (alpha > 0.5), so that the video does not flicker; pixels with
// alpha < 0.5 are black.
class VideoDepthColours {
 public:
  Image operator()(const torch::Tensor& depth, const torch::Tensor& alpha);

 private:
  bool have_range_ = false;
  float lo_ = 0, hi_ = 1;
};

}  // namespace ii
