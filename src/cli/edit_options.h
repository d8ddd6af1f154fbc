#pragma once
// The one-mask editing options shared by masks, prepare, infer and eval: a region marked on one
// view (--view, --mask) stands in for a mask on every view.
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "cli/runtime.h"
#include "edit/scene_masks.h"

namespace ii::cli {

// --inpainter's help; the caller appends the default's name.
inline const std::string kInpainterHelp =
    "The 2D inpainter that paints the reference's region when no --reference is given: telea, ns (OpenCV's diffusion: smooth), patch (patches of the photo copied inward), big-lama (the cache's LaMa: instainpaint models get big-lama; a learned inpainter, far better) or a LaMa file (big-lama.pt, big-lama/models/best.ckpt); default $INSTAINPAINT_INPAINTER, else auto: the cache's LaMa when it is there, else ";
// --checkpoint's help: what it takes and the default.
inline const std::string kCheckpointHelp =
    "The network's weights: auto (the default: InstaInpaint's released checkpoint when the cache holds it, "
    "instainpaint models get instainpaint; else the small model built in, models/MODEL_CARD.md), default (the "
    "built-in model), instainpaint (the cache's), or an official .pth or safetensors file";
// --segmenter's help: what it takes and the default.
inline const std::string kSegmenterHelp =
    "The segmentation network: auto (the default, else $INSTAINPAINT_SEGMENTER: the cache's MobileSAM or SAM, "
    "instainpaint models get mobile-sam; without one, none), none (no network), a catalogue name (mobile-sam, "
    "sam-vit-b, sam-vit-l, sam-vit-h) or a SAM / MobileSAM file as published (mobile_sam.pt, sam_vit_b_01ec64.pth)";

struct EditArgs {
  std::string view, mask;
  std::vector<std::string> clicks;      // --click X,Y (repeatable)
  std::vector<std::string> not_clicks;  // --not-click X,Y (repeatable; with --segmenter or --box)
  std::string box;                      // --box X0,Y0,X1,Y1
  std::string segmenter;                // --segmenter FILE (else $INSTAINPAINT_SEGMENTER)
  std::string mode = "remove";
  std::string depth;
  double depth_scale = 0.001;
  double extent = 0;        // 0 = the region's width in 3D
  double depth_margin = -1;  // < 0 = the depth source's own
  int dilate = -1;  // -1 = automatic
  std::string carve = "on";  // --carve: on, off
  std::string reference_view;       // --reference-view
  std::string inpainter;  // --inpainter (empty: $INSTAINPAINT_INPAINTER, else telea)
  double inpaint_grow = -1;  // --inpaint-grow (< 0: InputOptions' default)
  GeometryOptions geometry;  // add_geometry_options
};

// --view, --mask, --click, --not-click, --box, --segmenter, --mode, --depth, --depth-scale, --extent, --dilate.
void add_edit_options(CLI::App* cmd, EditArgs& args);
// --reference-view, --reference-inpainter and add_geometry_options (commands that build the
// network's input).
void add_reference_options(CLI::App* cmd, EditArgs& args);
// What is done with the network's output, into `geometry` as the options are parsed: a flag per
// row of geometry/settings.h's table (--align-depth, --measured-surface, --frame-margin, ...).
void add_geometry_options(CLI::App* cmd, GeometryOptions& geometry);
// --align-depth and --depth-detail alone (add_geometry_options adds them too).
void add_align_depth_option(CLI::App* cmd, GeometryOptions& geometry);

// The request the options describe for this scene, or nullopt without --view/--mask. `precision`
// (--precision: auto, fp32, bf16) is the segmenter's too.
std::optional<OneMask> one_mask_request(const EditArgs& args, const Scene& scene, const std::string& precision);
// The reference options into the network's input options.
void apply_reference_options(const EditArgs& args, SceneInputOptions& options);

// The model, loaded on first use: a one-mask edit needs the network only when no other depth
// of the marked view exists.
class LazyPredictor {
 public:
  LazyPredictor(std::string checkpoint, RuntimeOptions runtime)
      : checkpoint_(std::move(checkpoint)), runtime_(std::move(runtime)) {}
  const Predictor& get();
  PredictorSource source() {
    return [this]() -> const Predictor& { return get(); };
  }
  const Predictor* loaded() const { return predictor_ ? &*predictor_ : nullptr; }

 private:
  std::string checkpoint_;
  RuntimeOptions runtime_;
  std::optional<Predictor> predictor_;
};

}  // namespace ii::cli
