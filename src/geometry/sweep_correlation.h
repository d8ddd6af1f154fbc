#pragma once
// The inner loop of the plane sweep (geometry/stereo_depth.h): how well a reference picture's
// windows match another picture warped onto many depths. One pass per depth over the pixels:
// project, sample, and sum the windows in place. Written as LibTorch operations it made some forty
// passes over (depths x pixels) tensors, and the sweep cost 0.24 s of the page's edit on 2 cores.
#include "camera/camera.h"
#include "common/torch.h"

namespace ii {

// The normalised cross-correlation (D, h, w) float32 of `reference_grey`'s (h, w) windows of
// `window` x `window` pixels (the part inside the picture near its border) with `source_grey`
// (its camera's size) sampled bilinearly, zero outside, where each reference pixel's point lies at
// each of `depths` (D, h * w; camera z, the cameras' units); -1 where that point is behind the
// source camera or outside its picture. Both cameras are at their pictures' sizes.
torch::Tensor sweep_correlation(const torch::Tensor& reference_grey, const Camera& reference_camera,
                                const torch::Tensor& source_grey, const Camera& source_camera,
                                const torch::Tensor& depths, int window);

}  // namespace ii
