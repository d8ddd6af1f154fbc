#pragma once
// Refinement: a short optimisation of predicted Gaussians against every view of the capture,
// starting from the network's prediction (the feed-forward pass sees a few views; a capture
// has dozens). 3DGS's parametrisation and per-parameter learning rates, Adam, loss
// L1 + λ (1 − SSIM). Each view supervises outside its object mask; the reference (the
// inpainted image the network saw) supervises everywhere, so the hole keeps its content.
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "camera/camera.h"
#include "data/preprocess.h"
#include "gaussians/gaussians.h"
#include "io/image.h"
#include "model/predictor.h"

namespace ii {

struct RefineView {
  std::string name;
  Image rgb;                  // 3 channels, [0,1]
  std::optional<Image> mask;  // 1 channel at the image's size; > 0.5 = not supervised
  Camera camera;              // for `rgb`, in the Gaussians' frame
};

struct RefineOptions {
  int steps = 300;
  double ssim_weight = 0.2;  // λ
  uint64_t seed = 0;         // the order the views are visited in
  // 0: one colour per Gaussian (as the network predicts); 1-3: view-dependent colour, SH
  // coefficients of this degree fitted from zero (3DGS's rate: colour_lr / 20).
  int sh_degree = 0;
  // Adam learning rates (3DGS's); positions are scaled by the set's extent.
  double position_lr = 1.6e-4, scale_lr = 5e-3, rotation_lr = 1e-3, opacity_lr = 5e-2, colour_lr = 2.5e-3;
  std::function<void(int done, int total, double loss)> progress;  // after each step
};

struct RefineResult {
  // float32 on the start set's device; fully transparent ones dropped; RGB colours for
  // sh_degree 0, else SH of that degree.
  GaussianSet gaussians;
  std::vector<double> losses;  // per step
  double ms_per_step = 0;
  int64_t dropped = 0;  // Gaussians whose opacity ended below 1/255
};

// `start` has RGB colours (sh_degree -1), like the network's. Errors: no views, a view whose
// mask does not fit its image, steps < 0, an SH degree outside 0-3.
RefineResult refine_gaussians(const GaussianSet& start, const std::vector<RefineView>& views,
                              const RefineOptions& options);

// The supervising views of a prediction: every input view of the scene (not its test views)
// at the working size with its object mask (given, propagated or the scene's, as for the
// network's inputs), cameras in the prediction's normalised frame; the reference first, as the
// inpainted image the network saw, unmasked.
std::vector<RefineView> refinement_views(const Scene& scene, const Prediction& prediction,
                                         const SceneInputOptions& options);

// Both of the above for a prediction: `start` (its Gaussians, on the device to refine on)
// refined against the scene's views; `report` receives {"steps", "ms_per_step", "views",
// "losses", "dropped"} for run.json / metrics.json.
GaussianSet refine_prediction(const Scene& scene, const Prediction& prediction, const SceneInputOptions& options,
                              const GaussianSet& start, const RefineOptions& refine, nlohmann::json& report);

}  // namespace ii
