#pragma once
// Gaussians past the edges of each context view's picture. A camera a little behind, below or
// beside the context cameras sees ground that none of them saw; with one Gaussian per input
// pixel it shows the renderer's background there (white, as the official renderer's), the
// largest single loss on real captures (SPIn-NeRF scene 1: a band at the bottom of every test
// view). Each view's border Gaussians are continued outward: the pixel grid extended past the
// frame, each new pixel taking its nearest border pixel's depth, colour, opacity, scale and
// rotation along its own ray; those another context view sees through are then dropped (a
// repeated border is no evidence against what a photo saw).
#include <cstdint>
#include <vector>

#include <nlohmann/json.hpp>

#include "camera/camera.h"
#include "data/preprocess.h"
#include "gaussians/gaussians.h"
#include "model/model_input.h"

namespace ii {

struct FrameMarginOptions {
  // How far past each edge, as a fraction of the view's height (0: none). One Gaussian per pixel
  // there as inside: a sparser margin of wider Gaussians (every second pixel, twice as wide and as
  // opaque as four) lost 0.02-0.36 dB on every held-out set for a margin a quarter the size.
  double fraction = 0.125;
  // Past that, out to this fraction of the height, one Gaussian per outer_stride x outer_stride block of
  // pixels, as wide as the block and as opaque as its pixels' over each other (no more than `fraction`,
  // or `fraction` 0: none). Measured (2026-11-29, 8d35f13; docs/usage.md, "The steps after the network,
  // measured"): to a quarter, every pixel or one per 2 x 2 block gave the same (SPIn-NeRF scene 1
  // +1.1 dB, make demo's feed-forward whole image +1.9 and most white patches at its frames' edges gone,
  // the rooms' whole images +0.2-0.3, statue and fern +-0.04) for a quarter of the Gaussians; 3 x 3
  // blocks or out to a half (4 x 4) lost 0.1-0.15 dB on scene 1, out to 3/8 gained nothing more.
  double outer_fraction = 0.25;
  int64_t outer_stride = 2;
  // Drop the margin's Gaussians that another context view sees through: in front of the depth that view
  // saw at their pixel (outside its mask), where it saw farther, so that space is empty. A view's border
  // repeated outward stood in front of what the others saw (SPIn-NeRF scene 1: bands of streaks over the
  // bricks and gravel). Measured (2026-11-28, 066a47e; docs/usage.md, "The steps after the network,
  // measured"): the scene's whole image +0.17 dB with the official reference, +0.82 with the object-free
  // photo; the held-out rooms' whole images +0.36 / +0.60 (128 / 256 rows, their regions +0.10 / +0.17),
  // the statue +0.08, the fern +0.11; a tolerance of 10 % in front (the floaters') gained a third as
  // much, fading instead of dropping less.
  bool drop_seen_through = true;
};

// The margin's Gaussians of every view of `maps` (the network's output for `input`, B = 1, after
// any depth alignment), in the maps' dtype and device; an empty set when options.fraction is 0.
GaussianSet gaussians_beyond_frame(const GaussianMaps& maps, const ModelInput& input,
                                   const FrameMarginOptions& options);

// `margin` (Gaussians added where no view saw: gaussians_beyond_frame's or gaussians_behind_edges'
// for `maps`) without those a context view sees through (geometry/floaters.h: `views` their masks,
// `cameras` in the maps' frame).
GaussianSet without_seen_through(const GaussianSet& margin, const GaussianMaps& maps,
                                 const std::vector<PreparedView>& views, const std::vector<Camera>& cameras);

// Its width in pixels at a view `height` pixels high: the dense band's, and the whole margin's.
int64_t frame_margin_pixels(int64_t height, const FrameMarginOptions& options);
int64_t frame_margin_outer_pixels(int64_t height, const FrameMarginOptions& options);

// What run.json and metrics.json record of it: `gaussians` kept, `dropped` seen through.
nlohmann::json describe_frame_margin(const FrameMarginOptions& options, int64_t height, int64_t gaussians,
                                     int64_t dropped = 0);

}  // namespace ii
