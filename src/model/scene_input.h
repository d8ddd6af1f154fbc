#pragma once
// From a Scene to the network's input: choose the context views, preprocess them, put the
// 2D-inpainted reference in place, normalise poses over the scene's cameras, build tensors.
// Shared by the prepare, infer and eval commands.
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "common/stage_times.h"
#include "data/inpaint2d.h"
#include "data/preprocess.h"
#include "data/scene.h"
#include "gaussians/gaussians.h"
#include "model/floaters.h"
#include "model/behind_edges.h"
#include "model/frame_margin.h"
#include "model/measured_surface.h"
#include "model/model_input.h"
#include "model/region_cover.h"
#include "model/region_surface.h"

namespace ii {

// Which of a scene's own 3D points the network's depth is aligned to. COLMAP's sparse points are
// not the default: on the fern they scaled the views' depth by 0.90-0.97 and its held-out views
// lost 0.4 dB (16.88 -> 16.50; session 16's weights: 0.6), where the points triangulated from the
// context views' photos (0.97-1.02) gained 0.1 and the synthetic rooms' depth maps gained too
// (see the model card).
enum class DepthPoints { none, depth_maps, photos, any };
const char* depth_points_name(DepthPoints points);  // "none", "depth-maps", "photos", "any"
DepthPoints parse_depth_points(const std::string& name);  // an Error naming the choices

// Predictor::predict, with align_depth: how closely each view's depth follows the scene's points
// beyond one scale per view (model/depth_alignment.h).
struct DepthDetailOptions {
  // The correction's width in point spacings (the mean distance between the points the view sees
  // outside its mask; 0 = one scale per view).
  double detail = 1.5;
  double prior = 0.3;      // the points' weight that pulls the correction back to the view's scale
  double max_ratio = 3.0;  // the most one point corrects, either way
  double front = 1.2;      // a point this much farther than the nearest beside it counts as hidden
  // Inside a view's mask the correction is this many times wider: the hole's depth follows its
  // wider surroundings rather than the edge of the object that stood there (held-out rooms at
  // 256², 2 spacings: 23.92 dB masked with the same width, 25.46 with 3x; docs/benchmarks.md).
  double region_factor = 4;
};

// What Predictor::predict does with the network's output before it makes Gaussians of it: each
// step is recorded under "geometry" in run.json and metrics.json. One struct, so that the
// commands, the server and the Python layer carry the steps whole: a new step is one field here.
struct GeometryOptions {
  // Each context view's depth scaled to the scene's own 3D points (model/depth_alignment.h):
  // those of its depth maps (synthetic scenes), else points triangulated from the context views'
  // photos (the default: on real captures the default model's depth is 1.3-5x too near), or
  // with `any` its COLMAP points before the photos', or none (the network's output as it is,
  // the paper's).
  DepthPoints align_depth = DepthPoints::photos;
  DepthDetailOptions depth_detail;
  // With align_depth other than none: where a context view has its own depth map (a depth
  // camera's, a synthetic scene's), its Gaussians outside its mask lie on that surface as flat,
  // opaque splats (model/measured_surface.h); opacity 0 = none.
  MeasuredSurfaceOptions measured_surface;
  // With a measured surface: the reference's region on the measured depth around it, chosen by
  // colour, as opaque flat splats (model/region_surface.h); opacity 0 = none. Off for an
  // insertion, whose region holds a new object rather than what lies behind.
  RegionSurfaceOptions region_surface;
  // Gaussians on a view's depth edges that another view sees through keep a fraction of their
  // opacity (model/floaters.h); fade 1 = none (the paper's).
  FloaterOptions floaters;
  // Each view's Gaussians continued past the edges of its picture (model/frame_margin.h);
  // fraction 0 = none (the paper's).
  FrameMarginOptions frame_margin;
  // The far side of each view's depth edges continued under the near side
  // (model/behind_edges.h); fraction 0 = none (the paper's).
  BehindEdgesOptions behind_edges;
  // The reference's region covered by flat splats besides the network's Gaussians
  // (model/region_cover.h); opacity 0 = none (the paper's).
  RegionCoverOptions region_cover;

  // Every step off: the network's Gaussians as the paper's code makes them.
  static GeometryOptions papers();
};

struct SceneInputOptions {
  std::vector<std::string> context;  // view names, reference first; empty = automatic
  int num_views = 4;                 // when choosing automatically
  std::string reference_view;        // when choosing automatically: this view is the reference
  // The 2D-inpainted reference image, at the reference photo's size or the working size:
  // in memory (wins) or a file; neither = classical inpainting of the reference (`inpainter`).
  std::optional<Image> reference_image;
  std::string reference_image_source = "image in memory";  // what SceneInput::reference_source says of it
  std::optional<std::filesystem::path> reference;
  ClassicalInpainter inpainter = ClassicalInpainter::Telea;
  // Object masks by view name, at the view's image size (> 0.5 = object): they replace the
  // scene's own masks of those views, so a caller needs no mask files.
  std::map<std::string, Image> masks;
  PreprocessOptions preprocess;
  // Reconstruct the scene as captured: photos unmasked, mask channels zero, the reference's
  // own photo (no masks needed; `reference` is ignored).
  bool keep_object = false;
  // Where the context views come from when set (a server's edits): views prepared before.
  PreparedViewCache* view_cache = nullptr;
  // What Predictor::predict does with the network's Gaussians before it returns them.
  GeometryOptions geometry;
};

struct SceneInput {
  std::vector<int> context;              // indices into scene.views, reference first
  std::vector<PreparedView> views;       // working-size views; views[0].rgb = inpainted
  PoseNormalization normalization;       // fitted over all cameras of the scene
  ModelInput input;
  std::string reference_source;          // file name, "image in memory", or "telea" / "ns" when made here
};

// `stages` (optional) gets "prepare context views" (read, decode, resize, masks), the
// reference's stage ("inpaint reference (telea)" or "read reference") and "network input".
SceneInput prepare_scene_input(const Scene& scene, const SceneInputOptions& options, StageTimes* stages = nullptr);

// The reference as prepare_scene_input makes it when none is given: view `view`'s working image
// with `mask` (at the view's image size, > 0.5 = region) filled by options.inpainter. A caller
// may make it ahead, beside other work (serve: beside the mask propagation), and pass it as
// reference_image.
Image classical_reference(const Scene& scene, const std::string& view, const Image& mask,
                          const SceneInputOptions& options);

// The views `indices` of scene.views at the working size with their object masks, the
// caller's (options.masks) in place of the scene's. Every view after the first (the reference)
// needs a mask unless options.keep_object; the error calls them `role`s ("context view").
// The views are read and resized at once, on the thread plan's cores.
std::vector<PreparedView> prepare_masked_views(const Scene& scene, const std::vector<int>& indices,
                                               const SceneInputOptions& options, const std::string& role);

// Gaussians between the pose-normalised frame the network works in and the scene's own frame
// (its cameras', as 3DGS trainers write splats): positions scaled and shifted, scales scaled.
// Files are written in the scene's frame, so that they line up with the capture and with
// other tools' splats; `infer --normalized` keeps the network's.
GaussianSet in_scene_frame(const GaussianSet& gaussians, const PoseNormalization& normalization);
GaussianSet in_normalized_frame(const GaussianSet& gaussians, const PoseNormalization& normalization);

}  // namespace ii
