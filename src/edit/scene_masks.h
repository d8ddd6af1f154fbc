#pragma once
// Editing a scene from one mask: the region a user marked on one view becomes a mask for every
// view (edit/propagate.h), lifted with the best depth of that view there is: a depth file the
// user gives, else the scene's COLMAP points, else the network's own reconstruction of the
// scene as captured.
//
//   OneMask edit{"IMG_2707", read_mask("region.png")};
//   const SceneMasks m = masks_from_one(scene, edit, [&]() -> const Predictor& { return predictor; }, input_options);
//   m.apply_to(input_options, edit);  // masks, and the marked view as the reference
//   predictor.predict(scene, input_options);
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "data/scene.h"
#include "common/stage_times.h"
#include "edit/carve.h"
#include "edit/propagate.h"
#include "edit/select.h"
#include "predict/predictor.h"
#include "segment/segmenter.h"

namespace ii {

struct OneMask {
  std::string view;  // name of the marked view (one of scene.views)
  Image region;      // 1 channel at that view's image size, > 0.5 = marked
  PropagationOptions propagation;  // its depth_margin is replaced by the source's unless `depth_margin` is set
  std::optional<double> depth_margin;
  std::optional<std::filesystem::path> depth_file;  // see read_depth_map (data/masks.h)
  double depth_png_scale = 0.001;                   // scene units per level of a 16-bit depth PNG
  // The marked view's depth already made (a reconstruction of the scene rendered at its working
  // camera): (H, W) camera z at the working size in the pose-normalised frame, taken as the
  // network's would be (its margin), before the network runs; `working_depth_source` names it.
  std::optional<torch::Tensor> working_depth;
  std::string working_depth_source = "given depth";
  // With the network's reconstruction: each propagated mask carved to the object it holds
  // (edit/carve.h); false: the propagated masks as they are. On by default (docs/editing.md,
  // "Carved to the object": scene 1 from any view's true mask 0.989 / 0.886 carved).
  bool carve = true;
  CarveOptions carving;
  // Clicks on the view in place of `region`. With a segmenter, its mask of the clicked view
  // (points on the object: `clicks`, points that are not: `not_clicks`) becomes the region,
  // lifted and carved (`carve`) like a drawn one. Without, the object under each click is selected in the
  // network's reconstruction (edit/select.h) and each view's mask carved to it.
  std::vector<Click> clicks, not_clicks;
  // A box around the object on the view, with or without clicks inside it: with a segmenter its
  // prompt; without, GrabCut in it (edit/box_select.h) makes the region, lifted and carved.
  std::optional<ViewBox> box;
  std::shared_ptr<const Segmenter> segmenter;
  SelectOptions selecting;
};

// A region mask file for a view: read_mask, then checked against the view's image size.
Image read_region_mask(const std::filesystem::path& file, const View& view);

// How far each depth source may be off (relative), i.e. the slack the lifted segments get:
// a depth file is taken as exact, COLMAP points as accurate but sparse, the network's
// reconstruction as biased (the default model's depth of the statue scene is about 25 % far;
// its segments also span the region's whole depth range instead of starting at each pixel's).
constexpr double kFileDepthMargin = 0.05, kColmapDepthMargin = 0.1, kNetworkDepthMargin = 0.3;

// Sparse depth of a view from the scene's COLMAP points (the nearest point per pixel; 0 where
// none falls); nullopt when the scene has no points.
std::optional<Image> colmap_points_depth(const Scene& scene, const View& view);

// The network's z-depth of `view` (scene units, at the view's image size; 0 outside the
// working crop), reconstructed with the object present: that view is the reference, the
// other context views are chosen around it, nothing is masked.
// `stages` (optional) gets the prediction's stages, prefixed "masks: ".
Image predicted_view_depth(const Predictor& predictor, const Scene& scene, const std::string& view,
                           const SceneInputOptions& options, StageTimes* stages = nullptr);
// The same reconstruction's depth of `view` and its Gaussians' centres (scene frame, the opaque
// ones, at most `max_points` of them evenly taken).
constexpr int64_t kReconstructionPoints = 400000;
struct ViewReconstruction : ColouredPoints {
  Image depth;
};
// The centres and RGB colours (their own, or their SH's DC term's) of the Gaussians of `g` at
// `rows` (indices), on the CPU.
ColouredPoints coloured_points(const GaussianSet& g, const torch::Tensor& rows);
// Those of its opaque Gaussians (above 0.5): what a click selects among.
ColouredPoints opaque_points(const GaussianSet& g);

// The options of the scene's reconstruction with the object kept that a click on a view selects
// in, as the page makes it when it opens: the reference chosen automatically, `options`' working
// size, number of views, geometry and view cache. One reconstruction for the page and the
// commands: the same click gives the same mask of the clicked view in both.
SceneInputOptions scene_reconstruction_options(const SceneInputOptions& options);

// The objects under `clicks` on `view` among `points` (seen by `camera`: the view's camera in the
// points' frame; `scene_far` the scene's far bound in that frame, when known), and their outline
// on the view carved by its photo (edit/select.h, edit/carve.h).
struct ClickedOutline {
  Image mask;                     // 0/1 at the view's size
  std::vector<uint8_t> selected;  // per point
};
ClickedOutline outline_of_clicks(const View& view, const Camera& camera, const ColouredPoints& points,
                                 const std::vector<Click>& clicks, std::optional<double> scene_far,
                                 const SelectOptions& selecting = {}, const CarveOptions& carving = {});
ViewReconstruction predicted_view_reconstruction(const Predictor& predictor, const Scene& scene,
                                                 const std::string& view, const SceneInputOptions& options,
                                                 StageTimes* stages = nullptr,
                                                 int64_t max_points = kReconstructionPoints);

struct SceneMasks {
  std::map<std::string, Image> masks;  // every view of the scene by name; the marked one = its region
  std::string depth_source;            // "file <path>", "colmap points" or "network"
  std::vector<std::string> notes;      // why a preferred depth source was passed over
  std::vector<LiftedRegion> regions;
  int carved = 0;  // views whose masks were carved to the object (edit/carve.h)
  int64_t selected = 0, points = 0;  // clicks': the reconstruction's points selected, of all
  // How the clicked view's mask was made: "segmenter" (with `segmenter`: the network and the mask
  // it chose), "GrabCut in the box" or "colour growth over the reconstruction"; empty without
  // clicks or a box.
  std::string clicked_mask;
  nlohmann::json segmenter;
  // {"view", "mode", "depth_source", "notes", "regions": [{pixels, depth_inside, depth_ring, near, far}]}
  nlohmann::json describe(const OneMask& request) const;
  // Gives the network these masks; the marked view becomes the reference unless the caller
  // chose one (options.reference_view or options.context).
  void apply_to(SceneInputOptions& options, const OneMask& request) const;
};

// The predictor (asked for only when the network's depth is needed, so a caller can load it
// lazily; may be empty, which is then an error naming the other sources) runs with `options`'
// preprocessing and number of context views. `stages` (optional) gets the work's stages,
// named "masks: ..." (the depth's prediction, "masks: propagate").
using PredictorSource = std::function<const Predictor&()>;
// A depth map of `view` at the working size of `preprocess` ((H, W) camera z in the pose-normalised
// frame, whose scale is `normalization_scale`) at the view's image size in scene units.
Image depth_at_image_size(const torch::Tensor& working_depth, double normalization_scale, const View& view,
                          const PreprocessOptions& preprocess);

SceneMasks masks_from_one(const Scene& scene, const OneMask& request, const PredictorSource& predictor,
                          const SceneInputOptions& options, StageTimes* stages = nullptr);

// The segmenter's mask of `view`'s photo (segment/segmenter.h's mask_from_clicks, or
// mask_from_prompt with a box). An Error names a click or a box outside the view.
ClickedMask segmented_view_mask(const Segmenter& segmenter, const View& view, const std::vector<Click>& clicks,
                                const std::vector<Click>& not_clicks, StageTimes* stages = nullptr,
                                const std::optional<ViewBox>& box = std::nullopt);

}  // namespace ii
