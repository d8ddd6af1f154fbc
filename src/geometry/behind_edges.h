#pragma once
// Gaussians behind each context view's depth edges. With one Gaussian per pixel nothing lies
// behind a view's near surface: a camera a little beside it looks past the near edge, and where no
// other context view saw that ground it sees the renderer's background (white, dotted patches
// beside make demo's table once the views' surfaces became sharp, opaque splats). The far side of
// each depth edge is continued under the near side: each near pixel within a few pixels of an
// edge gets a Gaussian on its own ray at the far side's depth, with the far side's attributes;
// those another context view sees through are then dropped (geometry/frame_margin.h's test).
#include <cstdint>
#include <vector>

#include <nlohmann/json.hpp>

#include "data/preprocess.h"
#include "gaussians/gaussians.h"
#include "model/model_input.h"

namespace ii {

// Measured (2026-11-29, 8d35f13; feed-forward; docs/usage.md, "The steps after the network, measured"):
// a 32nd of the height gained the held-out rooms' whole images 0.21 / 0.72 dB (128 / 256 rows) and make
// demo's 0.51 / 1.29 (whole / masked), left SPIn-NeRF scene 1, the statue and the fern within 0.04, for
// 19 % more Gaussians. A 16th closed make demo's last white slivers but lost the statue 0.13; the
// farthest deeper pixel as the source, not the far side of an edge, smeared a slanted floor's colours
// (rooms -0.5); the far side next to the edge carried the near side's colour (brown smears); one
// Gaussian per 2 x 2 block lost the fern 0.13.
struct BehindEdgesOptions {
  // How far under the near side, as a fraction of the view's height (0: none).
  double fraction = 0.03125;
  // ... this many times as far where the context views' depth is their depth maps: an edge there
  // is where the map says, and the ground behind it is the map's (2026-11-29, with the maps' flying
  // pixels on the far side: make demo's last white sliver closed, +0.22 dB whole, the held-out
  // rooms +0.02 / +0.03 masked; a 16th everywhere had lost the statue 0.13).
  double depth_map_factor = 2;
  // A depth edge: the far side more than this fraction farther than its nearest neighbour.
  double jump = 0.1;
};

// The Gaussians behind the depth edges of every view of `maps` (the network's output for
// `input`, B = 1, after the measured surface and the floaters; `views` their masks), in the maps'
// dtype and device; an empty set when options.fraction is 0. The far side is taken two pixels
// from the edge, where a photo's colour no longer blends both sides, and only outside the view's
// mask; the near pixels too lie outside it.
GaussianSet gaussians_behind_edges(const GaussianMaps& maps, const ModelInput& input,
                                   const std::vector<PreparedView>& views, const BehindEdgesOptions& options);

// The options for depth that is its depth maps' (`depth_maps`): the fraction times depth_map_factor.
BehindEdgesOptions behind_edges_for(const BehindEdgesOptions& options, bool depth_maps);

// How far under the near side in pixels at a view `height` pixels high.
int64_t behind_edges_pixels(int64_t height, const BehindEdgesOptions& options);

// What run.json and metrics.json record of it: `gaussians` kept, `dropped` seen through.
nlohmann::json describe_behind_edges(const BehindEdgesOptions& options, int64_t height, int64_t gaussians,
                                     int64_t dropped);

}  // namespace ii
