#pragma once
// Flat splats that tile a view's pixels on a surface given by its depth: one Gaussian per pixel,
// lying on the surface and sized to reach its neighbours, so that a camera elsewhere sees no gap
// between them. `fill` places its hole's content this way; a prediction covers the reference's
// region with them (geometry/region_cover.h).
#include "camera/camera.h"
#include "common/torch.h"
#include "gaussians/gaussians.h"
#include "io/image.h"

namespace ii {

// One Gaussian per `take` pixel (H, W bool) of `camera`: at `depth` (H, W; camera z, every take
// pixel and its neighbours where known), coloured by `colour` (the camera's size), flat along the
// surface with its two axes 0.7 times the distance to the neighbouring pixels' points (at most 4
// pixels' footprint: a seam in the depth is no surface), of `opacity`. (0.7 and 0.99 against 0.5
// and 0.95: 0.1 dB more in SPIn-NeRF scene 1's region seen from elsewhere, fewer pixels left
// uncovered there, the reference's own view a little softer.)
GaussianSet surface_gaussians(const Camera& camera, const torch::Tensor& depth, const torch::Tensor& take,
                              const Image& colour, float opacity = 0.99f, double width = 0.7);

// A backing for surface_gaussians' splats: the same `take` pixels at half the camera's size, each
// 2 x 2 block's farthest pixel (its depth, 1 % behind, and its colour). Where another camera looks
// between the front splats (over a seam in the depth), it meets the hole's colours rather than
// nothing; from the camera itself the front splats hide it. SPIn-NeRF scene 1: the 4 pixels of
// one reference's fill that showed the background in two test views covered, the region's PSNR
// the same to 0.01 dB; the synthetic rooms 0.02-0.14 dB lower, where the room behind a seam
// showed through and now the backing does (backed only where nothing is behind in the camera
// itself: the rooms unchanged, scene 1's 4 pixels open again).
GaussianSet backing_gaussians(const Camera& camera, const torch::Tensor& depth, const torch::Tensor& take,
                              const Image& colour, float opacity = 0.99f);

}  // namespace ii
