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
#include "model/model_input.h"

namespace ii {

// What prepare_scene_input makes of a scene (the Predictor's SceneInputOptions adds what it does
// after the network: predict/predictor.h).
struct InputOptions {
  std::vector<std::string> context;  // view names, reference first; empty = automatic
  int num_views = 4;                 // when choosing automatically
  std::string reference_view;        // when choosing automatically: this view is the reference
  // The 2D-inpainted reference image, at the reference photo's size or the working size:
  // in memory (wins) or a file; neither = classical inpainting of the reference (`inpainter`).
  std::optional<Image> reference_image;
  std::string reference_image_source = "image in memory";  // what SceneInput::reference_source says of it
  std::optional<std::filesystem::path> reference;
  Inpainter inpainter;
  // The region `inpainter` paints: the reference's mask grown by this fraction of its larger side
  // (at least a pixel when above 0), so that what rims the object in the photo (its contact
  // shadow, edge pixels) is painted over rather than continued inward. The network's own mask
  // input stays the reference's mask. Unset: the mask as it is, unless the region was selected
  // (a click or a box: SceneMasks::apply_to sets kSelectionInpaintGrow).
  std::optional<double> inpaint_grow;
  // Object masks by view name, at the view's image size (> 0.5 = object): they replace the
  // scene's own masks of those views, so a caller needs no mask files.
  std::map<std::string, Image> masks;
  PreprocessOptions preprocess;
  // Reconstruct the scene as captured: photos unmasked, mask channels zero, the reference's
  // own photo (no masks needed; `reference` is ignored).
  bool keep_object = false;
  // Where the context views come from when set (a server's edits): views prepared before.
  PreparedViewCache* view_cache = nullptr;
};

struct SceneInput {
  std::vector<int> context;              // indices into scene.views, reference first
  std::vector<PreparedView> views;       // working-size views; views[0].rgb = inpainted
  PoseNormalization normalization;       // fitted over all cameras of the scene
  ModelInput input;
  std::string reference_source;          // file name, "image in memory", or "telea" / "ns" / "lama" when made here
  nlohmann::json reference_inpainter;    // when made here: the inpainter (Inpainter::describe); else null
};

// `stages` (optional) gets "prepare context views" (read, decode, resize, masks), the
// reference's stage ("inpaint reference (telea)" or "read reference") and "network input".
SceneInput prepare_scene_input(const Scene& scene, const InputOptions& options, StageTimes* stages = nullptr);

// The reference as prepare_scene_input makes it when none is given: view `view`'s working image
// with `mask` (at the view's image size, > 0.5 = region) filled by options.inpainter. A caller
// may make it ahead, beside other work (serve: beside the mask propagation), and pass it as
// reference_image.
Image painted_reference(const Scene& scene, const std::string& view, const Image& mask, const InputOptions& options);
// The region a 2D inpainter paints for `mask` (at its working size): grown by `grow` of its larger side.
Image region_to_paint(const Image& mask, double grow);
// The growth of a selected region (a click's or a box's outline lies on the object's edge, its rim
// and contact shadow outside). Measured (docs/editing.md, "The painted region"): the model card's
// rooms marked by a box (GrabCut), Navier-Stokes, region PSNR 23.44 -> 23.70 dB at 1 % (3 of 4
// rooms up by 0.59-0.84, one down 1.10), 23.51 at 2 %, 22.86 at 4 %; with their exact labels
// growth costs 0.27 dB at 1 %: a given mask is painted as it is.
constexpr double kSelectionInpaintGrow = 0.01;

// The views `indices` of scene.views at the working size with their object masks, the
// caller's (options.masks) in place of the scene's. Every view after the first (the reference)
// needs a mask unless options.keep_object; the error calls them `role`s ("context view").
// The views are read and resized at once, on the thread plan's cores.
std::vector<PreparedView> prepare_masked_views(const Scene& scene, const std::vector<int>& indices,
                                               const InputOptions& options, const std::string& role);

// Gaussians between the pose-normalised frame the network works in and the scene's own frame
// (its cameras', as 3DGS trainers write splats): positions scaled and shifted, scales scaled.
// Files are written in the scene's frame, so that they line up with the capture and with
// other tools' splats; `infer --normalized` keeps the network's.
GaussianSet in_scene_frame(const GaussianSet& gaussians, const PoseNormalization& normalization);
GaussianSet in_normalized_frame(const GaussianSet& gaussians, const PoseNormalization& normalization);

}  // namespace ii
