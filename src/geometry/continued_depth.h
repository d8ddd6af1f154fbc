#pragma once
// A hole's depth continued from the depth known around it: fill's hole in a splat scene, where the kept
// scene's rendered depth around a view's hole is exact and a network's depth of a real capture is off.
// Harmonic in inverse depth, so a plane stays a plane; fill then lays one flat splat per hole pixel on
// it (geometry/surface_splats.h). The reference's region of a prediction takes its depth from its
// surroundings by colour instead (geometry/region_surface.h); the two measured on fill's path, SPIn-NeRF
// scene 1 with three object-free photos as references: this one's region 17.16 / 17.70 / 15.70 dB, the
// region surface's 16.74 / 16.99 / 14.86 with 3,470 pixels left uncovered in 88 views against 131 in 27
// (2026-12-03, 2242c94; docs/editing.md, "Fill the hole in any splat scene (`instainpaint fill`, serve's
// *Fill*, `Gaussians.fill`)").
#include <optional>

#include "common/torch.h"

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
