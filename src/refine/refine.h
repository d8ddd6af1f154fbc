#pragma once
// Refinement: a 3DGS optimisation of predicted Gaussians against every view of the capture,
// starting from the network's prediction (the feed-forward pass sees a few views; a capture
// has dozens). 3DGS's parametrisation, per-parameter learning rates and adaptive density
// control (clone, split, prune), Adam, loss L1 + λ (1 − SSIM), coarse to fine, optional
// per-view colour correction. Each view supervises outside its object mask; the reference
// (the inpainted image the network saw) supervises everywhere, so the hole keeps its content.
#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <utility>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "camera/camera.h"
#include "data/preprocess.h"
#include "gaussians/gaussians.h"
#include "io/image.h"
#include "predict/predictor.h"
#include "refine/densify.h"

namespace ii {

struct RefineView {
  std::string name;
  Image rgb;                  // 3 channels, [0,1]
  std::optional<Image> mask;  // 1 channel at the image's size; > 0.5 = not supervised
  Camera camera;              // for `rgb`, in the Gaussians' frame
  // Whether it may be held out to score the iterates (RefineOptions::hold_out_every): not a view
  // the start was made from, which it reproduces better than any other.
  bool may_hold_out = true;
  // With a mask: what to fit inside it instead of leaving it free (refine_prediction: what the
  // start draws there). The held-out scores still read the image's own pixels alone.
  std::optional<Image> in_mask;
};

// Where a refinement stands, after each step.
struct RefineProgress {
  int step = 0;           // steps done
  double fraction = 0;    // of the run: steps / steps asked for, or time used / time budget
  double loss = 0;        // of this step
  double elapsed_s = 0;
  double eta_s = 0;
  int64_t gaussians = 0;  // now
};

// 3DGS's initial position learning rate (× the scene's extent).
constexpr double kGaussianSplattingPositionLr = 1.6e-4;

struct RefineOptions {
  int steps = 300;           // how long, unless time_budget_s is set
  double time_budget_s = 0;  // > 0: optimise until this many seconds have passed (steps is then ignored)
  double ssim_weight = 0.2;  // λ
  std::array<float, 3> background{1.f, 1.f, 1.f};  // behind the Gaussians in every render of the run
  uint64_t seed = 0;         // the order the views are visited in
  // 0: one colour per Gaussian (as the network predicts); 1-3: view-dependent colour, SH
  // coefficients up to this degree fitted from zero (3DGS's rate: colour_lr / 20), one degree
  // more at each tenth of the run, as 3DGS raises it over its first 3000 of 30000 steps.
  int sh_degree = 0;
  // Adam learning rates, 3DGS's but for positions: scaled by the set's extent, starting at 30 times
  // 3DGS's and decaying exponentially to position_lr_final (over the run, or sooner:
  // position_decay_views). From the network's raw depth (off by a good part of a real scene) 300x was
  // best; from the whole prediction, on the measured surfaces, 300x shakes what is right (2026-12-02,
  // 76931df; docs/benchmarks.md, "Refinement (`--refine`)": `fast` on the fern 26.6 dB at 300x, 28.1 at
  // 30x; the statue 22.6 / 24.7; scene 1 whole 22.2 / 23.3; 10x 22.9; the synthetic rooms like 10x).
  double position_lr = 30 * kGaussianSplattingPositionLr, position_lr_final = kGaussianSplattingPositionLr,
         scale_lr = 5e-3, rotation_lr = 1e-3, opacity_lr = 5e-2, colour_lr = 2.5e-3;
  // The position rate's decay ends by the end of the run or after this many views' worth of
  // pixels (a quarter-resolution view counts 1/16), whichever comes first (0: the run alone).
  // A long run otherwise spends thousands of steps at rates that shake Gaussians which are
  // already right, and fits the supervising views at the held-out views' cost.
  double position_decay_views = 600;
  // Per-view colour correction for captures whose exposure and white balance change between
  // photos: an affine colour map per view (3x3 + offset, from the identity) applied to the
  // render before the loss; the first view's colours (the reference) are taken as they are.
  // Off by default: on captures of steady exposure (fern) the maps absorb part of what the
  // Gaussians should learn, and held-out views have no map.
  bool exposure = false;
  double exposure_lr = 1e-3;
  // Coarse to fine: the run at a quarter of the resolution until quarter_until, then at half
  // until half_until (fractions of the run): cheaper steps while the large errors are fixed.
  bool coarse_to_fine = true;
  double quarter_until = 0.1, half_until = 0.3;
  // Before optimising, new Gaussians where a view's supervised pixels are not covered by the
  // start set (opacity < 0.5): one per pixel of the quarter-resolution view, at the median depth
  // of what that view does see, in the photo's colour.
  bool cover = true;
  // refine_prediction only: start from the prediction's Gaussians of every n-th pixel row and
  // column of each context view (and every n²-th of the layers past the frames and behind the
  // depth edges), scales x n (n² times fewer: cheaper steps; densification adds detail where
  // the views ask for it).
  int start_stride = 3;
  DensifyOptions densify;  // between densify_from and densify_until of the run, every densify_every steps
  int densify_every = 50;
  double densify_from = 0.05, densify_until = 0.6;
  // The scene's size the position rate and the clone-or-split threshold are scaled by; 0: the
  // start set's visible radius (a prediction), > 0: given (reconstruct: 3DGS's camera extent).
  double extent = 0;
  // 3DGS's opacity reset, while densifying: at these fractions of the run every opacity is
  // lowered to at most reset_opacity (and its Adam moments forgotten); what the views need
  // becomes opaque again within ~100 steps, floaters that only some views need stay faint and
  // are pruned at the next densification. Empty: none.
  std::vector<double> opacity_resets = {0.2, 0.4};
  double reset_opacity = 0.01;
  // The result is the best of the start and the run's iterates on held-out views: every n-th
  // view after the first (the reference) is not fitted but scores them (0: none held out, the
  // last iterate is the result). Only with at least 3 views left to fit. Refinement then never
  // returns worse than it started, as those views see it.
  int hold_out_every = 8;
  // The run's iterates scored there, at these fractions of the run (the end is always one): after
  // the opacity resets and the densification, while the position rate has decayed.
  std::vector<double> score_at = {0.7, 0.85};
  std::function<void(const RefineProgress&)> progress;  // after each step
  // A run continued (reconstruct --resume): the steps already done, the schedule (rates,
  // densification, SH degree, resolution) taking up from there; the optimiser's moments start anew.
  int first_step = 0;
  double first_fraction = 0;  // of a time budget: the part already spent
  // Every checkpoint_every steps (0: never): the Gaussians as they stand (detached, the result's
  // form) and the steps done, for checkpoints and previews.
  int checkpoint_every = 0;
  std::function<void(int, const GaussianSet&)> checkpoint;
  // refine_prediction: each view's mask (the object, which the reference's region replaces) is fitted to
  // what the prediction draws there, instead of being left free: the moved Gaussians then do not grow
  // over the region where only masked views see it (make demo's room at 2,300 steps: the test views
  // 28.79 / 24.12 dB whole / masked refined without, 29.85 / 26.73 with, the feed-forward 29.01 / 27.86;
  // 2026-12-03, 2242c94; docs/benchmarks.md, "Refinement (`--refine`)"; CHANGELOG.md, 2026-12-03).
  bool start_in_masks = true;
  // Gaussians drawn with the optimised ones and never changed (a fill optimises its new
  // Gaussians alone in front of the rest of the scene; refine_prediction keeps the reference's
  // region as it was given); on the start set's device.
  GaussianSet fixed;
  // The whole scene the run stands for at its start, scored as the start on the held-out views
  // (refine_prediction: the prediction itself, every layer, before it was thinned); empty: the
  // start set drawn with the fixed ones.
  GaussianSet whole_start;
};

// `--refine`'s settings by name: "fast" (1 minute), "balanced" (9 minutes, what a user gets by default:
// on 2 cores the step count where scene 1's refined whole gains its 1 dB, 2026-12-03, 83c9a6f;
// docs/benchmarks.md, "Refinement (`--refine`)"), "best" (20 minutes), a time budget ("90s", "2m",
// "1.5m"), or a number of steps ("300"; "0" = no refinement). Error naming the text otherwise.
RefineOptions refine_setting(const std::string& text);
// Whether the options ask for any optimisation.
bool refine_requested(const RefineOptions& options);
// What the setting is, for logs and reports: "300 steps", "5 minutes".
std::string refine_length(const RefineOptions& options);

struct RefineResult {
  // float32 on the start set's device; fully transparent ones dropped; RGB colours for
  // sh_degree 0, else SH of that degree.
  GaussianSet gaussians;
  std::vector<double> losses;  // per step
  int steps = 0;               // done
  double seconds = 0;          // the whole call
  double ms_per_step = 0;
  int64_t start_count = 0, covered = 0, cloned = 0, split = 0, pruned = 0;
  int64_t dropped = 0;  // Gaussians whose opacity ended below 1/255
  int opacity_resets = 0;
  std::vector<std::string> views;  // that supervised (views masked everywhere say nothing)
  // Per view, with exposure: the colour map's diagonal gains and offsets (R, G, B).
  std::vector<std::pair<std::string, std::array<double, 6>>> exposure;
  // The held-out views (RefineOptions::hold_out_every) and the PSNR over their supervised pixels
  // of the start (-1 without) and of each scored iterate (step, PSNR).
  std::vector<std::string> held_out;
  double start_psnr = -1;
  std::vector<std::pair<int, double>> iterates;
  // Whether the start scored best: `gaussians` is then the start set as given (its colours in the
  // result's form), and with RefineOptions::whole_start the caller's whole scene is the answer.
  bool kept_start = false;
  int chosen_step = 0;  // the step of the iterate returned (0: the start)
};

// `start` has RGB colours (sh_degree -1), like the network's, or SH (a run continued). Errors: no
// views, a view whose mask does not fit its image, steps < 0, a negative time budget, an SH degree
// outside 0-3.
RefineResult refine_gaussians(const GaussianSet& start, const std::vector<RefineView>& views,
                              const RefineOptions& options);

// The supervising views of a prediction: every input view of the scene (not its test views)
// at the working size with its object mask (given, propagated or the scene's, as for the
// network's inputs), cameras in the prediction's normalised frame; the reference first, as the
// inpainted image the network saw, unmasked.
std::vector<RefineView> refinement_views(const Scene& scene, const Prediction& prediction,
                                         const SceneInputOptions& options);

// What run.json / metrics.json record of a refinement.
nlohmann::json refinement_report(const RefineResult& result, const RefineOptions& options);

// The prediction as refine_prediction takes it: `gaussians` (every layer, in Prediction::gaussians()'s
// order, or the context views' pixels alone) split into the Gaussians that move, thinned by
// `stride`, and those kept as given: whatever the reference sees in its region (the region
// surface's pixels, else its mask; none with `keep_object`), whichever view made it, and the
// region's cover.
struct RefinementStart {
  GaussianSet moving, kept;
};
RefinementStart refinement_start(const GaussianSet& gaussians, const Prediction& prediction, bool keep_object,
                                 int stride);

// The moved Gaussians of a refinement (refinement_start's `moving`, refined) without those that
// the reference sees in its region: the region is the kept Gaussians' alone. Gaussians that moved
// or grew there were fitted by no view but the reference, from behind or beside the region's
// splats, and covered them from other cameras (scene 1 with an object-free reference: the region
// 19.55 → 20.71 dB, the whole 23.34 → 23.26). `dropped`, when given, receives how many went.
GaussianSet outside_the_region(const GaussianSet& moved, const Prediction& prediction, bool keep_object,
                               int64_t* dropped = nullptr);

// refine_gaussians against refinement_views for a prediction: `start` (its Gaussians, every
// layer, on the device to refine on) refined against the scene's views; `report` receives what
// refinement_report() makes, for run.json / metrics.json. Refinement only adds to what the prediction gives: the
// reference's region keeps the Gaussians it was given (the other views' masks hide it) and no
// moved one ends there, the rest starts thinned (RefineOptions::start_stride) and densifies, and
// the prediction itself is the answer unless an iterate scores better on the held-out views.
GaussianSet refine_prediction(const Scene& scene, const Prediction& prediction, const SceneInputOptions& options,
                              const GaussianSet& start, const RefineOptions& refine, nlohmann::json& report);

}  // namespace ii
