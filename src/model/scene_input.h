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
