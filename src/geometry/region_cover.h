#pragma once
// The reference's region covered without gaps. Inside the object's mask only the reference sees
// the scene (the masked context views' Gaussians there are nearly transparent: opacity 0.01), so
// its one layer of per-pixel Gaussians alone carries the hole, and from a camera elsewhere the
// background shows between them: white streaks where the object stood (SPIn-NeRF scene 1: 8 % of
// the region's colour was the background, 0.5 % elsewhere). Beside the network's Gaussians, each
// of the reference's region pixels gets one flat splat on its depth (geometry/surface_splats.h) in
// the reference's colour, faint enough that the network's own Gaussians still decide the look.
#include <nlohmann/json.hpp>

#include "camera/camera.h"
#include "data/preprocess.h"
#include "gaussians/gaussians.h"

namespace ii {

struct RegionCoverOptions {
  // The splats' opacity (0: none, the paper's Gaussians alone). 0.2-0.5 measured alike; 0.99 made
  // the region sharp and a few pixels off in other views, which PSNR and the eye both punish.
  double opacity = 0.3;
};

// The cover of `reference`'s mask (its working image and mask, the first context view) at
// `depth` (H, W: the network's z-depth of the reference after any alignment) seen by `camera`
// (the reference's camera in the frame of the depth); in `like`'s dtype and device. An empty set
// without a mask, with an empty mask, or when options.opacity is 0.
GaussianSet region_cover_gaussians(const PreparedView& reference, const Camera& camera, const torch::Tensor& depth,
                                   const RegionCoverOptions& options, const torch::Tensor& like);

// What run.json and metrics.json record of it.
nlohmann::json describe_region_cover(const RegionCoverOptions& options, int64_t gaussians);

}  // namespace ii
