#pragma once
// From a Scene to the network's input: choose the context views, preprocess them, put the
// 2D-inpainted reference in place, normalise poses over the scene's cameras, build tensors.
// Shared by the prepare, infer and eval commands.
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "data/preprocess.h"
#include "data/scene.h"
#include "model/model_input.h"

namespace ii {

struct SceneInputOptions {
  std::vector<std::string> context;  // view names, reference first; empty = automatic
  int num_views = 4;                 // when choosing automatically
  // The 2D-inpainted reference image; absent = OpenCV Telea inpainting of the reference.
  std::optional<std::filesystem::path> reference;
  PreprocessOptions preprocess;
  // Reconstruct the scene as captured: photos unmasked, mask channels zero, the reference's
  // own photo (no masks needed; `reference` is ignored).
  bool keep_object = false;
};

struct SceneInput {
  std::vector<int> context;              // indices into scene.views, reference first
  std::vector<PreparedView> views;       // working-size views; views[0].rgb = inpainted
  PoseNormalization normalization;       // fitted over all cameras of the scene
  ModelInput input;
  std::string reference_source;          // file name, or "telea" when made here
};

SceneInput prepare_scene_input(const Scene& scene, const SceneInputOptions& options);

// The normalisation the official evaluation uses: over all cameras of the scene, input and
// test views alike (spec §5.1, normalize_mode "all").
PoseNormalization scene_normalization(const Scene& scene);

}  // namespace ii
