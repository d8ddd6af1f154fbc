#pragma once
// The hole's new surface from the scene's own geometry: a splat scene knows its surfaces exactly
// around the hole, where a network's depth of a real capture is off. The kept scene's depth on
// the pixels around a view's hole is continued inward (harmonic in inverse depth, so a plane
// stays a plane), and every hole pixel becomes one flat Gaussian of a picture's colour on that
// surface, sized to tile the view without gaps.
#include <optional>

#include "camera/camera.h"
#include "common/torch.h"
#include "gaussians/gaussians.h"
#include "io/image.h"

namespace ii {

// Continues `depth` (H, W; camera z) from the `known` pixels into the `unknown` ones (both (H, W)
// bool): Laplace's equation in inverse depth with the known pixels fixed, pixels that are
// neither left out. Coarse to fine. Returns the depth with the unknown pixels filled (the rest
// as given); nullopt when no known pixel touches the unknown ones' reach. (Neighbours weighed by
// their likeness in the reference's colours, for depth to follow its edges: 0.1 dB worse on
// SPIn-NeRF scene 1, more pixels left uncovered; not kept.)
std::optional<torch::Tensor> complete_depth(const torch::Tensor& depth, const torch::Tensor& known,
                                            const torch::Tensor& unknown);

// One Gaussian per `take` pixel (H, W bool) of `camera`: at `depth` (H, W; camera z, every take
// pixel and its neighbours where known), coloured by `colour` (the camera's size), flat along the
// surface with its two axes 0.7 times the distance to the neighbouring pixels' points (at most 4
// pixels' footprint: a seam in the depth is no surface), of `opacity`. (0.7 and 0.99 against 0.5
// and 0.95: 0.1 dB more in SPIn-NeRF scene 1's region seen from elsewhere, fewer pixels left
// uncovered there, the reference's own view a little softer.)
GaussianSet surface_gaussians(const Camera& camera, const torch::Tensor& depth, const torch::Tensor& take,
                              const Image& colour, float opacity = 0.99f);

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
