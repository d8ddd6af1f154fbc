#pragma once
// A depth camera's pixel that straddles an edge measures a depth between the two sides (so does a
// supersampled synthetic depth map, whose depth is the mean over the pixel), and its colour is a
// mix of both. Put where it was measured, its splat floats between the near surface and the far
// one: from another camera the rims of make demo's table sprayed dark specks over the floor.
// Each such pixel is moved to the far side of its edge and takes the colour of the far side's
// pixel next to it: the near side's edge stays where its own pixels draw it, and the far side's
// ground runs on behind it (on the near side, the table got a ring of the floor's colour; on the
// far side in its own mixed colour, a dark copy of the table's rim lay on the floor).
#include "common/torch.h"

namespace ii {

struct FlyingPixelOptions {
  // A pixel is flying where, along its row, its column or a diagonal, its two neighbours are this
  // far apart in log depth (an edge) ...
  double jump = 0.1;
  // ... it lies between them, this far from both in log depth ...
  double apart = 0.03;
  // ... and this far off their line in inverse depth (a plane's inverse depth is affine in the
  // pixel: a steep surface's pixels stay).
  double bend = 0.02;
  // The far side: the farthest depth this many pixels away that is not flying itself.
  int64_t reach = 3;
};

// Which pixels of `depth` (H, W; 0 or non-finite: unknown) are flying, (H, W) bool.
torch::Tensor flying_pixels(const torch::Tensor& depth, const FlyingPixelOptions& options);

struct FarSide {
  torch::Tensor depth;  // the depth map with each flying pixel at its far side's depth
  torch::Tensor moved;  // (H, W) bool: the flying pixels moved there
  torch::Tensor from;   // (H, W) int64: the pixel (row-major index) whose depth and colour each takes
};
FarSide flying_pixels_to_far_side(const torch::Tensor& depth, const FlyingPixelOptions& options);

// `colour` (3, H, W) with each moved pixel's colour taken from its `from` pixel.
torch::Tensor far_side_colours(const torch::Tensor& colour, const FarSide& far);

void check_flying_pixel_options(const FlyingPixelOptions& options);

}  // namespace ii
