#pragma once
// The forms Gaussians take in the project, and the one place that converts between them:
//
//   GaussianMaps  the network's output: per input pixel, (B, V, C, H, W), activated values
//        │ gaussians_from_maps (flattened in the official order: view, row, column)
//        ▼
//   GaussianSet   what the rasterizer draws: one row per Gaussian, activated values
//        ▲ gaussians_from_splats        │ splats_from_gaussians
//        │                               ▼
//   SplatCloud    a 3DGS PLY's pre-activation values (io/ply.h)
//
// The activations (sigmoid opacity, exponential scale, SH DC colour) and their inverses are
// written here and nowhere else.
#include <Eigen/Core>
#include "common/torch.h"

#include "io/ply.h"

namespace ii {

// Per-pixel Gaussian attributes, activated, each (B, V, C, H, W) float32.
struct GaussianMaps {
  torch::Tensor depth;     // C=1, z-depth
  torch::Tensor rgb;       // C=3, colour in [0,1] convention (no activation)
  torch::Tensor opacity;   // C=1, in (0,1)
  torch::Tensor scale;     // C=3, world units
  torch::Tensor rotation;  // C=4, unit quaternion (w, x, y, z)
  torch::Tensor xyz;       // C=3, world position
};

// Attributes of GaussianMaps, or-ed together: which of them a copy makes its own.
enum MapAttribute : unsigned {
  kDepthMap = 1,
  kRgbMap = 2,
  kOpacityMap = 4,
  kScaleMap = 8,
  kRotationMap = 16,
  kXyzMap = 32,
  kEveryMap = 63,
};

// A copy of each attribute in `which` that is there (contiguous, on the same device); the others
// are the same tensors as `maps`' (a step that writes some attributes copies only those).
GaussianMaps cloned(const GaussianMaps& maps, unsigned which = kEveryMap);

// Index `index` of dimension `dim` (0: the sample, 1: the view) of every attribute that is
// there, kept as a dimension of size 1: views of `maps`.
GaussianMaps narrowed(const GaussianMaps& maps, int64_t dim, int64_t index);

// Activated Gaussian parameters, one row per Gaussian, all float32 or float64 on one device
// (mixed float dtypes are converted to that of `means`).
struct GaussianSet {
  torch::Tensor means;      // (N, 3) world positions
  torch::Tensor quats;      // (N, 4) rotation (w, x, y, z), need not be normalised
  torch::Tensor scales;     // (N, 3) standard deviations (linear, not log)
  torch::Tensor opacities;  // (N) or (N, 1), in (0, 1)
  torch::Tensor colors;     // (N, 3) RGB when sh_degree < 0, else (N, K, 3) SH, K >= (d+1)²
  int sh_degree = -1;       // -1: colors are RGB; 0..3: SH degree used

  int64_t size() const { return means.defined() ? means.size(0) : 0; }
  GaussianSet to(const torch::Device& device) const;
};

// The rows where `take` (N, bool) is true, every attribute alike.
GaussianSet select_rows(const GaussianSet& gaussians, const torch::Tensor& take);

// `added` (RGB colours) drawn with `kept` (any colours): one set, `kept`'s rows first, colours as
// SH (the DC term alone) when kept's are.
GaussianSet joined(const GaussianSet& kept, const GaussianSet& added);

// The network output (B = 1) in the official flattening order (view, row, column), RGB
// colours used as they are (no activation; spec §3.1). The rows are views of the maps.
GaussianSet gaussians_from_maps(const GaussianMaps& maps);

// exp(log_scales), sigmoid(opacity_logit), rotations as stored (render() normalises), and
// the SH coefficients (N, K, 3) with K = 1 + sh_rest_per_channel, limited to
// `max_sh_degree` (the DC term alone is degree 0: colour = 0.5 + kSh0 dc, clamped at 0).
// float32 on the CPU.
GaussianSet gaussians_from_splats(const SplatCloud& cloud, int max_sh_degree = 3);

// The standard 3DGS parameterisation, float32 on the CPU: log scales (of at least 1e-12),
// opacity logits (opacities clamped to [1e-6, 1 - 1e-6] first), zero normals; RGB colours
// (sh_degree -1) become the DC term, SH colours are written up to the set's degree.
SplatCloud splats_from_gaussians(const GaussianSet& gaussians);

// Where the set is, for framing it in a view: the centre and half-diagonal of the box that
// holds the middle 96% of the visible splats (opacity > 0.1; all when none is) along each axis,
// so that a few floaters do not decide it.
struct BoundingSphere {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double radius = 0;
};
BoundingSphere visible_bounds(const GaussianSet& gaussians);

// Colour of the SH DC term alone, and back: rgb = 0.5 + kSh0 dc.
torch::Tensor rgb_from_sh_dc(const torch::Tensor& dc);
torch::Tensor sh_dc_from_rgb(const torch::Tensor& rgb);

}  // namespace ii
