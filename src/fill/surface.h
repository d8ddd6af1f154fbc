#pragma once
// The hole's new surface from the scene's own geometry: a splat scene knows its surfaces exactly
// around the hole, where a network's depth of a real capture is off. The kept scene's depth on
// the pixels around a view's hole is continued inward (harmonic in inverse depth, so a plane
// stays a plane), and every hole pixel becomes one flat Gaussian of a picture's colour on that
// surface, sized to tile the view without gaps (geometry/surface_splats.h).
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

}  // namespace ii
