#pragma once
// What cameras saw, and which points they see through or on: the one test of visibility that the
// steps after the network (geometry/floaters.h, frame_margin.h, behind_edges.h) and fill (the
// region's hole, the new splats that would hide what was seen) share. A point `seen through` by a
// view lands inside its picture, where its depth is known, nearer than that depth by more than a
// tolerance; a point on its surface lands there within the tolerance of it. Each caller's
// tolerance is its own, measured: 10 % for the network's flying pixels, 3 % for fill's rendered
// depth, 0 for the Gaussians past the frames.
#include <cstdint>
#include <vector>

#include "camera/camera.h"
#include "common/torch.h"
#include "data/preprocess.h"
#include "gaussians/gaussians.h"

namespace ii {

// A camera's depth (H, W; camera z) and where it is the scene's (H, W bool), on one device.
struct SeenDepth {
  Camera camera;
  torch::Tensor depth, usable;
};

// Each context view's depth in `maps` (the network's output, B = 1) with its camera, usable outside
// its mask (inside, the network guessed): on the maps' device.
std::vector<SeenDepth> seen_depths(const GaussianMaps& maps, const std::vector<PreparedView>& views,
                                   const std::vector<Camera>& cameras);

// Which of `points` (N, 3) a view of `seen` other than `skip` sees through: (N) bool.
torch::Tensor seen_through(const torch::Tensor& points, const std::vector<SeenDepth>& seen, double tolerance,
                           int64_t skip = -1);

// Which of `points` (N, 3) lie on the surface `seen` shows: (N) bool.
torch::Tensor on_seen_surface(const torch::Tensor& points, const SeenDepth& seen, double tolerance);

}  // namespace ii
