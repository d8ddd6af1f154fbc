#pragma once
// Building a GaussianSet (activated values, what render() takes) from the other forms the
// project holds Gaussians in: a splat PLY (pre-activation, as 3DGS stores them) and the
// network's per-pixel maps.
#include "io/ply.h"
#include "model/network.h"
#include "render/rasterizer.h"

namespace ii {

// exp(log_scales), sigmoid(opacity_logit), rotations as stored (render() normalises), and
// the SH coefficients (N, K, 3) with K = 1 + sh_rest_per_channel, limited to
// `max_sh_degree` (the DC term alone is degree 0: colour = 0.5 + 0.2820948 dc, clamped at 0).
// float32 on the CPU.
GaussianSet gaussians_from_splats(const SplatCloud& cloud, int max_sh_degree = 3);

// The network output (B = 1) in the official flattening order (view, row, column), RGB
// colours used as they are (no activation; spec §3.1).
GaussianSet gaussians_from_maps(const GaussianMaps& maps);

}  // namespace ii
