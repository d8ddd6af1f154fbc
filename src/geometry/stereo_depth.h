#pragma once
// Depth measured from the photos themselves: a plane sweep between the context views. Where a
// capture has no depth camera, its context views still see the same surfaces from a few
// centimetres apart; a patch of one photo that matches its neighbours' pictures at one depth and
// at no other measures that depth, as a depth camera would. Each view's depth is swept over
// planes parallel to its picture, matched by normalised cross-correlation (exposure changes
// between phone photos cancel) against every other view, the best two kept (the third may see
// something else in front); a depth stays only where it is distinct and another view's own sweep
// agrees with it. Where nothing is textured or the views disagree, the depth is unknown (0) and
// the network's Gaussians stay (geometry/measured_surface.h).
#include <utility>
#include <vector>

#include "camera/camera.h"
#include "common/torch.h"
#include "io/image.h"

namespace ii {

// Measured on SPIn-NeRF scene 1, the statue and the fern (2026-11-28, 67e4edf; docs/usage.md, "The steps
// after the network, measured"): 24, 32 or 48 depths, 96-192 rows gave the same held-out figures to
// 0.05 dB; a least correlation of 0.3 and agreement within 4 % knew 62 % of scene 1's pixels instead of
// 44 % (0.5 and 2 %), the statue +0.1 dB, the fern +0.15, each view's own picture +1.5; within 1 % lost
// 0.3 dB.
struct StereoOptions {
  int planes = 24;       // depths tried per pixel, evenly in log depth about the guide's
  double spread = 1.6;   // from the guide's depth / spread to its depth x spread
  double guide_smoothing = 0.3;  // the guide's log depth averaged over this fraction of the rows
  int rows = 128;        // matched at about this many rows (then brought back up to the pictures' size)
  int window = 5;        // the matched patches' side, in pixels at that size
  double min_ncc = 0.3;  // a depth whose best match correlates less is unknown
  // Another view's own depth must agree within this relative difference where the point lands.
  double consistency = 0.04;
};

// `photos` (3 channels, each its camera's size) and `cameras` of two or more views; `guides` a
// depth (H, W; camera z, the cameras' units) per view about which to search, e.g. a network's.
// Returns each view's depth (H, W) float32, camera z at its picture's size; 0 = unknown.
std::vector<torch::Tensor> stereo_depth(const std::vector<Image>& photos, const std::vector<Camera>& cameras,
                                        const std::vector<torch::Tensor>& guides, const StereoOptions& options = {});

}  // namespace ii
