#pragma once
// The surface a depth camera measured, used where a capture has it. A view with its own depth map
// (`<scene>/depth/<view>.npy`: a depth camera's, a synthetic scene's) knows each pixel's depth
// exactly, which the network and the alignment to points only approach. Without depth maps, the
// context photos measure it where they are textured and agree (geometry/stereo_depth.h). Outside
// the view's mask its Gaussians are put at that depth and made flat splats along the measured surface
// (geometry/surface_splats.h), opaque: the default model's Gaussians are needles along their rays
// of opacity ~0.4, which from another camera draw `make demo`'s table as a brown smear on the
// floor even at the exact depth; lying on the surface they draw the table, its pedestal and the
// floor's planks. Inside the mask the object stood: the network's Gaussians stay.
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "data/preprocess.h"
#include "data/scene.h"
#include "gaussians/gaussians.h"
#include "geometry/flying_pixels.h"
#include "geometry/stereo_depth.h"

namespace ii {

struct SceneInput;

// Measured on the held-out synthetic rooms (128 and 256 rows) and make demo's room (2026-11-28, bd2b3bc;
// docs/usage.md, "The steps after the network, measured"): opacity 0.6 lost the demo 1.6 dB; widths
// 0.2-0.7 traded the rooms against the demo; the margin traded the region against the views' own
// pictures.
struct MeasuredSurfaceOptions {
  // The splats' least opacity (0: none, the network's Gaussians as aligned to the points).
  double opacity = 0.95;
  // Their two axes, in distances to the neighbouring pixels' points: 0.25 barely overlaps, so
  // that a splat in front does not cover half its neighbour (0.7 drew the rooms a pixel off).
  double width = 0.25;
  // Pixels this close to the mask keep the network's Gaussians (unless beside the object, below):
  // their soft edge blends into the region's content where sharp splats stand against it (none:
  // the rooms' region 0.4 dB lower at 128 rows; 4 pixels: 0.4 dB higher, but the demo's views lost
  // their own pictures' edges around the masks, 32.6 -> 23.9 dB; 1 pixel: no figure under the
  // network's own).
  int mask_margin = 1;
  // Inside the other views' masks and margins, the scene beside the object (their measured points
  // outside the cone of the reference's mask grown by `cone_margin` pixels, or outside its
  // picture) lies on its surface too, in the photo's colours: a propagated mask is wider than the
  // object, and where every view but the reference masked the wall and floor the object hid, no
  // view's Gaussians were opaque (white patches in make demo's novel views). A 2-pixel cone lost
  // the rooms' region 0.15 dB.
  bool beside_object = true;
  int cone_margin = 10;
  // Where no context view has a depth map: each view's depth measured from the context photos
  // themselves (geometry/stereo_depth.h), used where it is known (SPIn-NeRF scene 1 +0.55 dB whole
  // image with the official reference, +0.83 with the true photo; the statue +0.46, the fern
  // +0.95; about 0.07 s on 2 cores at any working size, 0.15-0.2 s before its inner loop was one
  // pass per depth: geometry/sweep_correlation.h).
  bool from_photos = true;
  StereoOptions stereo;
  // A depth map's pixels that straddle an edge, moved to its far side (geometry/flying_pixels.h;
  // false: where they were measured). The held-out rooms +0.35 / +0.26 dB masked (128² / 256²),
  // make demo's room +0.33 (2026-11-29, 6144227; docs/usage.md, "The steps after the network, measured").
  bool far_side = true;
  FlyingPixelOptions flying;
};

// Where a measured depth came from: the steps that treat a depth map's slopes and edges as
// measured (the region surface, behind the depth edges) ask this, not the record's text.
enum class MeasuredFrom { nothing, depth_maps, photos };

struct MeasuredSurface {
  std::string source;              // "depth maps", "the photos (stereo)" or "" (none)
  MeasuredFrom from = MeasuredFrom::nothing;  // the same, typed
  std::vector<std::string> views;  // the context views that had a measured depth
  std::vector<double> known;       // ... the fraction of each one's pixels it covered
  int64_t gaussians = 0;           // the Gaussians put on their surface outside the masks
  int64_t beside_object = 0;       // ... inside them (and their margins): the scene beside the object
  int64_t far_side = 0;            // the depth maps' flying pixels moved to their far side
};

// Each context view's measured depth (H, W) at the working size in the pose-normalised frame's
// units, 0 where unknown: its depth map (`<scene>/depth/<view>.npy` at its photo's size), else
// undefined; without any depth map and with options.from_photos, the photos' stereo depth, searched
// about `maps`' depth (the network's, aligned).
struct MeasuredDepth {
  std::string source;
  MeasuredFrom from = MeasuredFrom::nothing;
  std::vector<torch::Tensor> depth;
  // With depth maps and MeasuredSurfaceOptions::far_side, each view's flying pixels moved to the
  // far side (default-constructed for the others).
  std::vector<FarSide> far_side;
};
MeasuredDepth measured_depth(const Scene& scene, const SceneInput& input, const PreprocessOptions& preprocess,
                             const GaussianMaps& maps, const MeasuredSurfaceOptions& options);

// In place on `maps` (the network's output for `input`; pose-normalised frame): each context view
// with a measured depth gets its outside-the-mask pixels' positions, depth, sizes, rotations and
// opacities from the measured surface where the depth is known; colours stay the network's.
// The view's mask grown by `grow` pixels (a square), (H, W) bool; all false without a mask.
torch::Tensor grown_mask(const PreparedView& view, int grow);

// Splats (rows in the order of `pixels`, flat indices of view `vi`) written over that view's maps:
// positions, `depth` (one per row), sizes, rotations, opacities at least the splats', and with
// `colours` their colours too.
void write_splats(GaussianMaps& maps, int64_t vi, const torch::Tensor& pixels, const GaussianSet& splats,
                  const torch::Tensor& depth, bool colours);
// Colours (N, 3) written over view `vi`'s maps at `pixels` (flat indices).
void write_colours(GaussianMaps& maps, int64_t vi, const torch::Tensor& pixels, const torch::Tensor& colours);

MeasuredSurface put_on_measured_surface(GaussianMaps& maps, const SceneInput& input, const MeasuredDepth& measured,
                                        const MeasuredSurfaceOptions& options);

// What run.json and metrics.json record of it.
nlohmann::json describe_measured_surface(const MeasuredSurfaceOptions& options, const MeasuredSurface& done);

}  // namespace ii
